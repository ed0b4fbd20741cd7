//! A [`TileSummary`] as bytes, so the summaries survive a restart (the server keeps them in its
//! tile store): a versioned, little-endian record, read back exactly or refused (never
//! misread).
//!
//! Layout (version 2): `CMS2`; the tile (`z` u8, `x` u32, `y` u32); `groups` u64; the region
//! (west, south, east, north, lowest, highest: f64); the reach (lon, lat: f64); the roof and
//! ground errors (f64); the ground cells (4 x u64); the block count (u16, at most 256); each
//! block: its cell (u16), its id (type u8: 0 way, 1 relation; id i64), the largest footprint,
//! then groups (u32), area, lon, lat, height (f64); the digest (u64). 143 bytes plus 55 per
//! block. A record of version 1 (no digest) is refused, and the summary made again.

use super::summary::{BLOCK_CELLS, Block, TileSummary};
use crate::geo::{Region, TileCoord};
use crate::osm::OsmId;
use crate::terrain::CellMask;

/// The first bytes of a summary record, with its version.
const MAGIC: &[u8; 4] = b"CMS2";

/// Blocks a summary holds at most: one per cell.
const MAX_BLOCKS: usize = (BLOCK_CELLS * BLOCK_CELLS) as usize;

/// Why bytes are not a summary.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SummaryBytesError {
    #[error("not a tile summary of version 2 (the record starts {0:02x?})")]
    Version(Vec<u8>),
    #[error("the summary ends early, at byte {0}")]
    Truncated(usize),
    #[error("{0} bytes follow the summary")]
    Trailing(usize),
    #[error("the summary has {0} blocks, more than {MAX_BLOCKS}")]
    TooManyBlocks(usize),
    #[error("a block's cell {0} is off the {BLOCK_CELLS} x {BLOCK_CELLS} grid")]
    Cell(u16),
    #[error("a block's id has type {0}, neither way (0) nor relation (1)")]
    IdType(u8),
    #[error("the summary's tile is not a tile: {0}")]
    Tile(String),
    #[error("the summary holds a number that is not finite")]
    NotFinite,
}

impl TileSummary {
    /// The summary as bytes (read back by [`TileSummary::from_bytes`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(143 + 55 * self.blocks.len());
        out.extend_from_slice(MAGIC);
        out.push(self.tile.z);
        out.extend_from_slice(&self.tile.x.to_le_bytes());
        out.extend_from_slice(&self.tile.y.to_le_bytes());
        out.extend_from_slice(&self.groups.to_le_bytes());
        let r = &self.region;
        for v in [
            r.west,
            r.south,
            r.east,
            r.north,
            r.min_height,
            r.max_height,
            self.reach.0,
            self.reach.1,
            self.roof_error_m,
            self.ground_error_m,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for word in self.ground_cells.0 {
            out.extend_from_slice(&word.to_le_bytes());
        }
        // At most 256 blocks by construction (one per cell).
        let count = u16::try_from(self.blocks.len()).unwrap_or(u16::MAX);
        out.extend_from_slice(&count.to_le_bytes());
        for (cell, b) in &self.blocks {
            out.extend_from_slice(&cell.to_le_bytes());
            let (kind, id) = match b.id {
                OsmId::Way(id) => (0u8, id),
                OsmId::Relation(id) => (1u8, id),
            };
            out.push(kind);
            out.extend_from_slice(&id.to_le_bytes());
            out.extend_from_slice(&b.largest_m2.to_le_bytes());
            out.extend_from_slice(&b.groups.to_le_bytes());
            for v in [b.area_m2, b.lon, b.lat, b.height_m] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out.extend_from_slice(&self.digest.to_le_bytes());
        out
    }

    /// The summary `bytes` hold, checked whole: a record of another version, cut short or
    /// followed by more, or holding what no summary holds, is an error.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, SummaryBytesError> {
        let mut r = Reader { bytes, at: 0 };
        let magic = r.take(4)?;
        if magic != MAGIC {
            return Err(SummaryBytesError::Version(magic.to_vec()));
        }
        let (z, x, y) = (r.u8()?, r.u32()?, r.u32()?);
        let tile = TileCoord::new(u32::from(z), x, y)
            .map_err(|e| SummaryBytesError::Tile(e.to_string()))?;
        let groups = r.u64()?;
        let region = Region {
            west: r.f64()?,
            south: r.f64()?,
            east: r.f64()?,
            north: r.f64()?,
            min_height: r.f64()?,
            max_height: r.f64()?,
        };
        let reach = (r.f64()?, r.f64()?);
        let (roof_error_m, ground_error_m) = (r.f64()?, r.f64()?);
        let ground_cells = CellMask([r.u64()?, r.u64()?, r.u64()?, r.u64()?]);
        let count = usize::from(r.u16()?);
        if count > MAX_BLOCKS {
            return Err(SummaryBytesError::TooManyBlocks(count));
        }
        let mut blocks = Vec::with_capacity(count);
        for _ in 0..count {
            let cell = r.u16()?;
            if usize::from(cell) >= MAX_BLOCKS {
                return Err(SummaryBytesError::Cell(cell));
            }
            let id = match (r.u8()?, r.i64()?) {
                (0, id) => OsmId::Way(id),
                (1, id) => OsmId::Relation(id),
                (kind, _) => return Err(SummaryBytesError::IdType(kind)),
            };
            let largest_m2 = r.f64()?;
            let groups = r.u32()?;
            blocks.push((
                cell,
                Block {
                    id,
                    largest_m2,
                    groups,
                    area_m2: r.f64()?,
                    lon: r.f64()?,
                    lat: r.f64()?,
                    height_m: r.f64()?,
                },
            ));
        }
        let digest = r.u64()?;
        if r.at != bytes.len() {
            return Err(SummaryBytesError::Trailing(bytes.len() - r.at));
        }
        Ok(Self {
            digest,
            tile,
            groups,
            region,
            reach,
            roof_error_m,
            ground_error_m,
            blocks,
            ground_cells,
        })
    }
}

/// Reads little-endian numbers off the front of a record.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], SummaryBytesError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or(SummaryBytesError::Truncated(self.bytes.len()))?;
        let out = &self.bytes[self.at..end];
        self.at = end;
        Ok(out)
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], SummaryBytesError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }

    fn u8(&mut self) -> Result<u8, SummaryBytesError> {
        Ok(self.array::<1>()?[0])
    }

    fn u16(&mut self) -> Result<u16, SummaryBytesError> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    fn u32(&mut self) -> Result<u32, SummaryBytesError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    fn u64(&mut self) -> Result<u64, SummaryBytesError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    fn i64(&mut self) -> Result<i64, SummaryBytesError> {
        Ok(i64::from_le_bytes(self.array()?))
    }

    fn f64(&mut self) -> Result<f64, SummaryBytesError> {
        let v = f64::from_le_bytes(self.array()?);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(SummaryBytesError::NotFinite)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn summary(blocks: Vec<(u16, Block)>) -> TileSummary {
        TileSummary {
            digest: 0x0123_4567_89ab_cdef,
            tile: TileCoord::new(14, 8574, 5623).unwrap(),
            groups: 1_460,
            region: Region {
                west: 8.39,
                south: 49.03,
                east: 8.41,
                north: 49.05,
                min_height: 101.25,
                max_height: 160.5,
            },
            reach: (0.0012, 0.0007),
            roof_error_m: 3.5,
            ground_error_m: 0.75,
            blocks,
            ground_cells: CellMask([1, u64::MAX, 0, 1 << 63]),
        }
    }

    fn block(id: OsmId, area_m2: f64) -> Block {
        Block {
            id,
            largest_m2: area_m2 / 2.0,
            groups: 7,
            area_m2,
            lon: 8.395,
            lat: 49.041,
            height_m: 9.25,
        }
    }

    #[test]
    fn a_summary_reads_back_exactly_and_has_the_documented_size() {
        let s = summary(vec![
            (0, block(OsmId::Way(142_104_398), 1_200.0)),
            (255, block(OsmId::Relation(-5), 80.5)),
        ]);
        let bytes = s.to_bytes();
        assert_eq!(bytes.len(), 143 + 2 * 55);
        assert_eq!(TileSummary::from_bytes(&bytes), Ok(s));
    }

    #[test]
    fn what_is_not_a_whole_summary_is_refused() {
        let bytes = summary(vec![(3, block(OsmId::Way(1), 10.0))]).to_bytes();
        for cut in 0..bytes.len() {
            assert!(
                matches!(
                    TileSummary::from_bytes(&bytes[..cut]),
                    Err(SummaryBytesError::Truncated(_) | SummaryBytesError::Version(_))
                ),
                "cut at {cut}"
            );
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(
            TileSummary::from_bytes(&longer),
            Err(SummaryBytesError::Trailing(1))
        );
        let mut other = bytes.clone();
        other[3] = b'1'; // a version 1 record (no digest) is made again, not misread
        assert!(matches!(
            TileSummary::from_bytes(&other),
            Err(SummaryBytesError::Version(_))
        ));
        // The block's id type, right after its cell.
        let mut kind = bytes.clone();
        kind[135 + 2] = 9;
        assert_eq!(
            TileSummary::from_bytes(&kind),
            Err(SummaryBytesError::IdType(9))
        );
        let mut cell = bytes.clone();
        cell[135..137].copy_from_slice(&256u16.to_le_bytes());
        assert_eq!(
            TileSummary::from_bytes(&cell),
            Err(SummaryBytesError::Cell(256))
        );
        let mut nan = bytes;
        nan[21..29].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(
            TileSummary::from_bytes(&nan),
            Err(SummaryBytesError::NotFinite)
        );
    }

    proptest! {
        #[test]
        fn any_bytes_are_a_summary_or_an_error(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            let _ = TileSummary::from_bytes(&bytes);
        }

        #[test]
        fn summaries_round_trip(
            cells in proptest::collection::btree_set(0u16..256, 0..40),
            area in 0.0f64..1e6,
            relation in any::<bool>(),
            id in any::<i64>(),
        ) {
            let blocks = cells
                .into_iter()
                .map(|c| {
                    let id = if relation { OsmId::Relation(id) } else { OsmId::Way(id) };
                    (c, block(id, area + f64::from(c)))
                })
                .collect();
            let s = summary(blocks);
            prop_assert_eq!(TileSummary::from_bytes(&s.to_bytes()), Ok(s));
        }
    }
}

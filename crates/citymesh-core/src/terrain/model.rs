//! Any number of HGT tiles seen as one seamless sample grid.
//!
//! Samples are addressed by global indices: column `i = lon * p` and row `j = lat * p` (counted
//! from the equator northwards), where `p` is the model's samples per degree. A file's shared edge
//! rows and columns map to the same global index, so an area across file edges has every sample
//! exactly once.

use super::hgt::{HgtTile, VOID};
use crate::geo::GeoBbox;
use std::sync::Arc;

/// One grid sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sample {
    /// A measured height in metres.
    Valid(f64),
    /// The file marks this sample as void (-32768): its ground cell stays empty.
    Void,
    /// No file covers this sample.
    Missing,
}

/// A set of HGT tiles and the resolution the ground grid is built at.
#[derive(Debug, Clone)]
pub struct ElevationModel {
    per_degree: u32,
    tiles: TileIndex,
}

/// The loaded files by their south-west corner, in a dense grid over the degrees they span: a
/// lookup is two subtractions and an index, with no hashing, since every ground sample takes one.
#[derive(Debug, Clone, Default)]
struct TileIndex {
    south: i32,
    west: i32,
    columns: usize,
    rows: usize,
    cells: Vec<Option<Arc<HgtTile>>>,
}

impl TileIndex {
    /// Files whose corner is not on the Earth (latitude -90..90, longitude -180..180) are left
    /// out: no sample lies there.
    fn new(tiles: Vec<Arc<HgtTile>>) -> Self {
        let tiles: Vec<_> = tiles
            .into_iter()
            .filter(|t| (-90..90).contains(&t.south()) && (-180..180).contains(&t.west()))
            .collect();
        let (Some(south), Some(west)) = (
            tiles.iter().map(|t| t.south()).min(),
            tiles.iter().map(|t| t.west()).min(),
        ) else {
            return Self::default();
        };
        let north = tiles.iter().map(|t| t.south()).max().unwrap_or(south);
        let east = tiles.iter().map(|t| t.west()).max().unwrap_or(west);
        // At most 180 x 360 cells.
        let rows = (i64::from(north) - i64::from(south) + 1) as usize;
        let columns = (i64::from(east) - i64::from(west) + 1) as usize;
        let mut cells = vec![None; rows * columns];
        for t in tiles {
            let at = (t.south() - south) as usize * columns + (t.west() - west) as usize;
            cells[at] = Some(t);
        }
        Self {
            south,
            west,
            columns,
            rows,
            cells,
        }
    }

    #[inline]
    fn get(&self, lat: i64, lon: i64) -> Option<&HgtTile> {
        let row = usize::try_from(lat - i64::from(self.south)).ok()?;
        let column = usize::try_from(lon - i64::from(self.west)).ok()?;
        if row >= self.rows || column >= self.columns {
            return None;
        }
        self.cells[row * self.columns + column].as_deref()
    }

    fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

impl Default for ElevationModel {
    fn default() -> Self {
        Self::new(Vec::new())
    }
}

impl ElevationModel {
    /// A model over these tiles. The grid takes the finest resolution among them (1200 samples per
    /// degree when there are none); coarser tiles are interpolated bilinearly onto it.
    pub fn new(tiles: Vec<Arc<HgtTile>>) -> Self {
        let per_degree = tiles.iter().map(|t| t.per_degree()).max().unwrap_or(1200);
        Self {
            per_degree,
            tiles: TileIndex::new(tiles),
        }
    }

    /// Sample steps per degree of the grid.
    pub fn per_degree(&self) -> u32 {
        self.per_degree
    }

    /// Whether no tile at all is loaded: the ground is the flat fallback plane.
    pub fn is_empty(&self) -> bool {
        self.tiles.is_empty()
    }

    /// The sample at global column `i`, row `j`.
    pub fn sample(&self, i: i64, j: i64) -> Sample {
        let p = i64::from(self.per_degree);
        let (lat, row) = (j.div_euclid(p), j.rem_euclid(p));
        let (lon, col) = (i.div_euclid(p), i.rem_euclid(p));
        // A sample on a file edge belongs to both neighbours: try the one that is loaded.
        let mut candidates = [(lat, lon, row, col); 4];
        let mut n = 1;
        if row == 0 {
            candidates[n] = (lat - 1, lon, p, col);
            n += 1;
        }
        if col == 0 {
            candidates[n] = (lat, lon - 1, row, p);
            n += 1;
        }
        if row == 0 && col == 0 {
            candidates[n] = (lat - 1, lon - 1, p, p);
            n += 1;
        }
        for &(lat, lon, row, col) in &candidates[..n] {
            if let Some(tile) = self.tiles.get(lat, lon) {
                return self.sample_in(tile, row, col);
            }
        }
        Sample::Missing
    }

    /// The 3 x 3 samples around `(i, j)`, `[dj + 1][di + 1]`: with one division and one file
    /// lookup when all nine lie inside one loaded file (the common case), else sample by sample.
    pub(crate) fn window(&self, i: i64, j: i64) -> [[Sample; 3]; 3] {
        let p = i64::from(self.per_degree);
        let (lat, row) = ((j - 1).div_euclid(p), (j - 1).rem_euclid(p));
        let (lon, col) = ((i - 1).div_euclid(p), (i - 1).rem_euclid(p));
        // Rows and columns 1..p-2 of a file: no edge sample, so this file answers all nine.
        if row >= 1
            && row + 2 < p
            && col >= 1
            && col + 2 < p
            && let Some(tile) = self.tiles.get(lat, lon)
        {
            return std::array::from_fn(|dj| {
                std::array::from_fn(|di| self.sample_in(tile, row + dj as i64, col + di as i64))
            });
        }
        std::array::from_fn(|dj| {
            std::array::from_fn(|di| self.sample(i - 1 + di as i64, j - 1 + dj as i64))
        })
    }

    #[inline]
    fn sample_in(&self, tile: &HgtTile, row: i64, col: i64) -> Sample {
        let q = i64::from(tile.per_degree());
        let p = i64::from(self.per_degree);
        let value = |r: i64, c: i64| match tile.raw(r as usize, c as usize) {
            Some(VOID) | None => None,
            Some(v) => Some(f64::from(v)),
        };
        if q == p || (row * q % p == 0 && col * q % p == 0) {
            return value(row * q / p, col * q / p).map_or(Sample::Void, Sample::Valid);
        }
        // A coarser tile: bilinear between its four surrounding samples.
        let (r0, c0) = (row * q / p, col * q / p);
        let (fr, fc) = (
            (row * q % p) as f64 / p as f64,
            (col * q % p) as f64 / p as f64,
        );
        let r1 = (r0 + 1).min(q);
        let c1 = (c0 + 1).min(q);
        match (value(r0, c0), value(r0, c1), value(r1, c0), value(r1, c1)) {
            (Some(a), Some(b), Some(c), Some(d)) => {
                let south = a + (b - a) * fc;
                let north = c + (d - c) * fc;
                Sample::Valid(south + (north - south) * fr)
            }
            _ => Sample::Void,
        }
    }

    /// The sample nearest to a point, in metres, or `None` where it is void or missing.
    pub fn nearest_sample(&self, lon: f64, lat: f64) -> Option<f64> {
        let p = f64::from(self.per_degree);
        match self.sample((lon * p).round() as i64, (lat * p).round() as i64) {
            Sample::Valid(h) => Some(h),
            Sample::Void | Sample::Missing => None,
        }
    }
}

/// The south-west corners of the 1x1 degree files a ground grid over `bbox` may read, including
/// the ring of extra cells around it and the neighbours of shared edges.
pub fn dem_tiles_for(bbox: &GeoBbox) -> Vec<(i32, i32)> {
    // Two SRTM3 steps of margin covers the ring of cells and the corners around them.
    let margin = 2.0 / 1200.0;
    let lat0 = (bbox.min_lat() - margin).floor() as i32;
    let lat1 = (bbox.max_lat() + margin).floor() as i32;
    let lon0 = (bbox.min_lon() - margin).floor() as i32;
    let lon1 = (bbox.max_lon() + margin).floor() as i32;
    let mut out = Vec::new();
    for lat in lat0..=lat1 {
        for lon in lon0..=lon1 {
            if (-90..90).contains(&lat) && (-180..180).contains(&lon) {
                out.push((lat, lon));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(south: i32, west: i32, f: impl Fn(usize, usize) -> i16) -> Arc<HgtTile> {
        let mut s = Vec::with_capacity(1201 * 1201);
        for r in (0..1201).rev() {
            for c in 0..1201 {
                s.push(f(r, c));
            }
        }
        Arc::new(HgtTile::from_samples(south, west, s).unwrap())
    }

    #[test]
    fn shared_edges_resolve_to_whichever_file_is_loaded() {
        let west = tile(49, 8, |r, c| (r + c) as i16);
        let m = ElevationModel::new(vec![west]);
        // Column 9.0 E belongs to N49E009 by index, which is not loaded: N49E008's east edge answers.
        assert_eq!(m.sample(9 * 1200, 49 * 1200 + 5), Sample::Valid(1205.0));
        assert_eq!(m.sample(9 * 1200 + 1, 49 * 1200 + 5), Sample::Missing);
        // Row 50.0 N likewise from the north edge.
        assert_eq!(m.sample(8 * 1200 + 3, 50 * 1200), Sample::Valid(1203.0));
    }

    #[test]
    fn coarse_tiles_are_interpolated_onto_a_fine_grid() {
        let coarse = tile(49, 8, |r, c| (10 * r + c) as i16);
        let fine = Arc::new(HgtTile::from_samples(49, 9, vec![7; 3601 * 3601]).unwrap());
        let m = ElevationModel::new(vec![coarse, fine]);
        assert_eq!(m.per_degree(), 3600);
        // Every third fine step is a coarse sample; between them, a bilinear blend.
        assert_eq!(m.sample(8 * 3600 + 3, 49 * 3600 + 6), Sample::Valid(21.0));
        assert_eq!(
            m.sample(8 * 3600 + 4, 49 * 3600 + 6),
            Sample::Valid(21.0 + 1.0 / 3.0)
        );
        assert_eq!(m.sample(9 * 3600 + 4, 49 * 3600 + 6), Sample::Valid(7.0));
    }
}

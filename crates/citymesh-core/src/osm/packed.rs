//! The packed data tile: the building records of one data tile (with what was skipped or
//! repaired there) in a compact binary form, as the store keeps them. It is read straight into
//! records, with no parsing of JSON and no assembling of rings.
//!
//! Layout (every integer a LEB128 varint, signed ones zigzagged, unless said otherwise):
//! - the magic `CMPK` and a version byte ([`PACKED_VERSION`]); a newer version is refused, never
//!   misread;
//! - a string table (count, then length and UTF-8 bytes of each): every tag key and value once;
//! - the records (count, then each): a flags byte (relation, part, how coordinates are kept),
//!   the id, the numbers of outer and inner rings, each ring's nodes, the tags as pairs of
//!   string indices;
//! - the skipped buildings (id, reason, optional bounds as raw `f64`s) and the repaired ones
//!   (id, what);
//! - since version 2, the member ways of each multipolygon (relation id, count, way ids as
//!   deltas), what a later change to one of those ways must redraw (version 1 has none);
//! - since version 3, after each multipolygon's way ids, each way's role (a byte: 1 inner, 0
//!   not) and node ids (count, then deltas), what a replication diff rebuilds it from.
//!
//! A ring node keeps its OSM node id (a delta from the previous id in the tile) and its
//! coordinates as deltas of whole 1e-7 degrees from the previous node. Coordinates are kept
//! exactly: a record whose `f64`s are not all what one of the two ways of reading whole 1e-7
//! degrees gives (a decimal number, as Overpass JSON has; nanodegrees times 1e-9, as OSM PBF
//! readers compute) keeps raw `f64`s. So unpacking gives back bit for bit what was packed, and
//! what is drawn does not depend on the store.

use super::OsmError;
use super::assemble::{
    BuildingRecord, MemberWays, OsmBuildings, OsmId, Repaired, Ring, RingNode, SkipReason, Skipped,
};
use foldhash::HashMap;

/// The first bytes of a packed data tile.
pub const PACKED_MAGIC: &[u8; 4] = b"CMPK";
/// The version of the layout written (and the newest read).
pub const PACKED_VERSION: u8 = 3;

/// What [`Repaired::what`] can say, in the order packed.
pub const REPAIRS: [&str; 2] = ["missing_inner_ring", "tag_too_long"];

const SKIP_REASONS: [SkipReason; 9] = [
    SkipReason::MissingNodes,
    SkipReason::MissingMembers,
    SkipReason::UnclosedWay,
    SkipReason::UnclosedRing,
    SkipReason::TooFewNodes,
    SkipReason::NoOuterRing,
    SkipReason::DegenerateFootprint,
    SkipReason::OutOfRange,
    SkipReason::TooLarge,
];

const RELATION: u8 = 1;
const PART: u8 = 2;
/// Bits 2-3 of a record's flags: how its coordinates are kept.
const SCHEME_SHIFT: u8 = 2;
const HAS_BOUNDS: u8 = 2;

/// How a record's coordinates are kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scheme {
    /// Raw `f64` bits.
    Raw = 0,
    /// Whole 1e-7 degrees `n`, read as `n / 1e7` (a decimal number with 7 places).
    Decimal = 1,
    /// Whole 1e-7 degrees `n`, read as `1e-9 * (100 n)` (nanodegrees, as PBF readers compute).
    Nano = 2,
}

impl Scheme {
    fn read(self, n: i64) -> f64 {
        match self {
            Scheme::Raw | Scheme::Decimal => n as f64 / 1e7,
            Scheme::Nano => 1e-9 * (n.saturating_mul(100)) as f64,
        }
    }

    /// The whole 1e-7 degrees that read back as exactly `v`, if any.
    fn units(self, v: f64) -> Option<i64> {
        if !(v.is_finite() && v.abs() <= 360.0) {
            return None;
        }
        let n = (v * 1e7).round() as i64;
        (self.read(n).to_bits() == v.to_bits()).then_some(n)
    }

    /// The first scheme that keeps every coordinate of `record` exactly.
    fn for_record(record: &BuildingRecord) -> Self {
        let all = |s: Scheme| {
            record
                .outers
                .iter()
                .chain(&record.inners)
                .flat_map(|r| &r.nodes)
                .all(|n| s.units(n.lon).is_some() && s.units(n.lat).is_some())
        };
        [Scheme::Decimal, Scheme::Nano]
            .into_iter()
            .find(|s| all(*s))
            .unwrap_or(Scheme::Raw)
    }
}

/// Whether `bytes` are a packed data tile (of any version).
pub fn is_packed(bytes: &[u8]) -> bool {
    bytes.starts_with(PACKED_MAGIC)
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

struct Writer {
    out: Vec<u8>,
    prev_id: i64,
    prev: [i64; 2],
}

impl Writer {
    fn uint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.out.push((v as u8) | 0x80);
            v >>= 7;
        }
        self.out.push(v as u8);
    }

    fn int(&mut self, v: i64) {
        self.uint(zigzag(v));
    }

    fn len(&mut self, n: usize) {
        self.uint(n as u64);
    }

    fn f64(&mut self, v: f64) {
        self.out.extend_from_slice(&v.to_le_bytes());
    }

    fn id(&mut self, id: OsmId) -> u8 {
        let (flag, n) = match id {
            OsmId::Way(n) => (0, n),
            OsmId::Relation(n) => (RELATION, n),
        };
        self.int(n);
        flag
    }

    fn ring(&mut self, ring: &Ring, scheme: Scheme) {
        self.len(ring.nodes.len());
        // 0: no node has an id, 1: every node has one, 2: each says.
        let with_ids = ring.nodes.iter().filter(|n| n.id.is_some()).count();
        let ids = match with_ids {
            0 => 0,
            n if n == ring.nodes.len() => 1,
            _ => 2,
        };
        self.out.push(ids);
        for node in &ring.nodes {
            if ids == 2 {
                self.out.push(u8::from(node.id.is_some()));
            }
            if let Some(id) = node.id {
                self.int(id.wrapping_sub(self.prev_id));
                self.prev_id = id;
            }
            match (scheme.units(node.lon), scheme.units(node.lat)) {
                (Some(x), Some(y)) if scheme != Scheme::Raw => {
                    self.int(x - self.prev[0]);
                    self.int(y - self.prev[1]);
                    self.prev = [x, y];
                }
                _ => {
                    self.f64(node.lon);
                    self.f64(node.lat);
                }
            }
        }
    }
}

/// Packs the buildings of one data tile. Records are kept in the order given.
pub fn pack(buildings: &OsmBuildings) -> Vec<u8> {
    pack_parts(
        &buildings.buildings.iter().collect::<Vec<_>>(),
        &buildings.skipped,
        &buildings.repaired,
        &buildings.member_ways.iter().collect::<Vec<_>>(),
    )
}

/// Packs records (by reference), skipped and repaired buildings and the member ways of the
/// multipolygons of one data tile.
pub fn pack_parts(
    records: &[&BuildingRecord],
    skipped: &[Skipped],
    repaired: &[Repaired],
    member_ways: &[&MemberWays],
) -> Vec<u8> {
    let mut strings: Vec<&str> = Vec::new();
    let mut index: HashMap<&str, usize> = HashMap::default();
    for r in records {
        for (k, v) in &r.tags {
            for s in [k.as_str(), v.as_str()] {
                let next = strings.len();
                if *index.entry(s).or_insert(next) == next {
                    strings.push(s);
                }
            }
        }
    }
    let mut w = Writer {
        out: Vec::with_capacity(64 + records.len() * 96),
        prev_id: 0,
        prev: [0, 0],
    };
    w.out.extend_from_slice(PACKED_MAGIC);
    w.out.push(PACKED_VERSION);
    w.len(strings.len());
    for s in &strings {
        w.len(s.len());
        w.out.extend_from_slice(s.as_bytes());
    }
    w.len(records.len());
    for r in records {
        let scheme = Scheme::for_record(r);
        let flags_at = w.out.len();
        w.out.push(0);
        let kind = w.id(r.id);
        w.out[flags_at] = kind | if r.is_part { PART } else { 0 } | (scheme as u8) << SCHEME_SHIFT;
        w.len(r.outers.len());
        w.len(r.inners.len());
        for ring in r.outers.iter().chain(&r.inners) {
            w.ring(ring, scheme);
        }
        w.len(r.tags.len());
        for (k, v) in &r.tags {
            w.len(index[k.as_str()]);
            w.len(index[v.as_str()]);
        }
    }
    w.len(skipped.len());
    for s in skipped {
        let flags_at = w.out.len();
        w.out.push(0);
        let kind = w.id(s.id);
        w.out[flags_at] = kind | if s.bounds.is_some() { HAS_BOUNDS } else { 0 };
        let reason = SKIP_REASONS
            .iter()
            .position(|r| *r == s.reason)
            .unwrap_or(0);
        w.out.push(reason as u8);
        for v in s.bounds.iter().flatten() {
            w.f64(*v);
        }
    }
    w.len(repaired.len());
    for r in repaired {
        let flags_at = w.out.len();
        w.out.push(0);
        w.out[flags_at] = w.id(r.id);
        // Every `what` assemble writes is in the list (a test checks).
        let what = REPAIRS.iter().position(|x| *x == r.what).unwrap_or(0);
        w.out.push(what as u8);
    }
    w.len(member_ways.len());
    let mut prev_relation = 0i64;
    for m in member_ways {
        w.int(m.relation.wrapping_sub(prev_relation));
        prev_relation = m.relation;
        w.len(m.ways.len());
        let mut prev_way = 0i64;
        for &way in &m.ways {
            w.int(way.wrapping_sub(prev_way));
            prev_way = way;
        }
        // Incomplete member lists (read from version 2) are written as unknown: no nodes.
        for i in 0..m.ways.len() {
            w.out
                .push(u8::from(m.inner.get(i).copied().unwrap_or(false)));
            let refs = m.refs.get(i).map_or(&[][..], Vec::as_slice);
            w.len(refs.len());
            let mut prev_ref = 0i64;
            for &r in refs {
                w.int(r.wrapping_sub(prev_ref));
                prev_ref = r;
            }
        }
    }
    w.out
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    prev_id: i64,
    prev: [i64; 2],
}

fn corrupt(what: &str) -> OsmError {
    OsmError::Packed(format!("corrupt packed data tile: {what}"))
}

impl Reader<'_> {
    fn byte(&mut self) -> Result<u8, OsmError> {
        let b = *self
            .bytes
            .get(self.at)
            .ok_or_else(|| corrupt("it ends early"))?;
        self.at += 1;
        Ok(b)
    }

    fn uint(&mut self) -> Result<u64, OsmError> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.byte()?;
            v |= u64::from(b & 0x7f) << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(corrupt("a number is too long"))
    }

    fn int(&mut self) -> Result<i64, OsmError> {
        self.uint().map(unzigzag)
    }

    /// A count of items each at least `min_bytes` long: no larger than what is left could hold,
    /// so a corrupt count cannot make the reader allocate without bound.
    fn count(&mut self, min_bytes: usize) -> Result<usize, OsmError> {
        let n = self.uint()?;
        let left = (self.bytes.len() - self.at) / min_bytes.max(1);
        usize::try_from(n)
            .ok()
            .filter(|n| *n <= left)
            .ok_or_else(|| corrupt("a count is larger than the data"))
    }

    fn f64(&mut self) -> Result<f64, OsmError> {
        let end = self.at + 8;
        let b = self
            .bytes
            .get(self.at..end)
            .ok_or_else(|| corrupt("it ends early"))?;
        self.at = end;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    fn id(&mut self, flags: u8) -> Result<OsmId, OsmError> {
        let n = self.int()?;
        Ok(if flags & RELATION != 0 {
            OsmId::Relation(n)
        } else {
            OsmId::Way(n)
        })
    }

    fn ring(&mut self, scheme: Scheme) -> Result<Ring, OsmError> {
        let n = self.count(2)?;
        let ids = self.byte()?;
        if ids > 2 {
            return Err(corrupt("unknown node id mode"));
        }
        let mut nodes = Vec::with_capacity(n);
        for _ in 0..n {
            let has_id = match ids {
                0 => false,
                1 => true,
                _ => self.byte()? != 0,
            };
            let id = if has_id {
                self.prev_id = self.prev_id.wrapping_add(self.int()?);
                Some(self.prev_id)
            } else {
                None
            };
            let (lon, lat) = if scheme == Scheme::Raw {
                (self.f64()?, self.f64()?)
            } else {
                let x = self.prev[0].wrapping_add(self.int()?);
                let y = self.prev[1].wrapping_add(self.int()?);
                self.prev = [x, y];
                (scheme.read(x), scheme.read(y))
            };
            nodes.push(RingNode { id, lon, lat });
        }
        Ok(Ring { nodes })
    }
}

/// Reads a packed data tile back into its buildings.
pub fn unpack(bytes: &[u8]) -> Result<OsmBuildings, OsmError> {
    if !is_packed(bytes) {
        return Err(OsmError::Packed("not a packed data tile".to_owned()));
    }
    let mut r = Reader {
        bytes,
        at: PACKED_MAGIC.len(),
        prev_id: 0,
        prev: [0, 0],
    };
    let version = r.byte()?;
    if !(1..=PACKED_VERSION).contains(&version) {
        return Err(OsmError::Packed(format!(
            "packed data tile of version {version}: this citymesh reads versions 1 to {PACKED_VERSION}; \
             run the citymesh that wrote it, or import the data again"
        )));
    }
    let n = r.count(1)?;
    let mut strings = Vec::with_capacity(n);
    for _ in 0..n {
        let len = r.count(1)?;
        let end = r.at + len;
        let s =
            std::str::from_utf8(&bytes[r.at..end]).map_err(|_| corrupt("a string is not UTF-8"))?;
        strings.push(s);
        r.at = end;
    }
    let string = |i: u64| {
        usize::try_from(i)
            .ok()
            .and_then(|i| strings.get(i))
            .map(|s| (*s).to_owned())
            .ok_or_else(|| corrupt("a tag names a string the table lacks"))
    };
    let mut out = OsmBuildings::default();
    let n = r.count(4)?;
    out.buildings.reserve(n);
    for _ in 0..n {
        let flags = r.byte()?;
        let scheme = match (flags >> SCHEME_SHIFT) & 3 {
            0 => Scheme::Raw,
            1 => Scheme::Decimal,
            2 => Scheme::Nano,
            _ => return Err(corrupt("unknown coordinate scheme")),
        };
        let id = r.id(flags)?;
        let (outers, inners) = (r.count(2)?, r.count(2)?);
        let mut rings = Vec::with_capacity(outers + inners);
        for _ in 0..outers + inners {
            rings.push(r.ring(scheme)?);
        }
        let inners = rings.split_off(outers);
        let mut tags = super::Tags::new();
        for _ in 0..r.count(2)? {
            let (k, v) = (r.uint()?, r.uint()?);
            tags.insert(string(k)?, string(v)?);
        }
        out.buildings.push(BuildingRecord {
            id,
            is_part: flags & PART != 0,
            outers: rings,
            inners,
            tags,
        });
    }
    for _ in 0..r.count(3)? {
        let flags = r.byte()?;
        let id = r.id(flags)?;
        let reason = *SKIP_REASONS
            .get(usize::from(r.byte()?))
            .ok_or_else(|| corrupt("unknown skip reason"))?;
        let bounds = if flags & HAS_BOUNDS != 0 {
            Some([r.f64()?, r.f64()?, r.f64()?, r.f64()?])
        } else {
            None
        };
        out.skipped.push(Skipped { id, reason, bounds });
    }
    for _ in 0..r.count(3)? {
        let flags = r.byte()?;
        let id = r.id(flags)?;
        let what = *REPAIRS
            .get(usize::from(r.byte()?))
            .ok_or_else(|| corrupt("unknown repair"))?;
        out.repaired.push(Repaired { id, what });
    }
    if version >= 2 {
        let mut relation = 0i64;
        for _ in 0..r.count(2)? {
            relation = relation.wrapping_add(r.int()?);
            let n = r.count(1)?;
            let mut ways = Vec::with_capacity(n);
            let mut way = 0i64;
            for _ in 0..n {
                way = way.wrapping_add(r.int()?);
                ways.push(way);
            }
            let (mut inner, mut refs) = (Vec::new(), Vec::new());
            if version >= 3 {
                for _ in 0..n {
                    inner.push(match r.byte()? {
                        0 => false,
                        1 => true,
                        _ => return Err(corrupt("unknown member role")),
                    });
                    let k = r.count(1)?;
                    let mut way_refs = Vec::with_capacity(k);
                    let mut node = 0i64;
                    for _ in 0..k {
                        node = node.wrapping_add(r.int()?);
                        way_refs.push(node);
                    }
                    refs.push(way_refs);
                }
            }
            out.member_ways.push(MemberWays {
                relation,
                ways,
                inner,
                refs,
            });
        }
    }
    if r.at != bytes.len() {
        return Err(corrupt("bytes after its end"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A coordinate as the readers make them: a 7-place decimal (Overpass JSON), nanodegrees
    /// times 1e-9 (PBF), or any `f64`.
    fn coordinate(max: f64) -> impl Strategy<Value = f64> {
        let units = -(max * 1e7) as i64..=(max * 1e7) as i64;
        prop_oneof![
            units.clone().prop_map(|n| n as f64 / 1e7),
            units.prop_map(|n| 1e-9 * (n * 100) as f64),
            -max..max,
        ]
    }

    fn ring() -> impl Strategy<Value = Ring> {
        let node = (
            proptest::option::of(any::<i64>()),
            coordinate(180.0),
            coordinate(85.0),
        )
            .prop_map(|(id, lon, lat)| RingNode { id, lon, lat });
        proptest::collection::vec(node, 3..12).prop_map(|nodes| Ring { nodes })
    }

    fn id() -> impl Strategy<Value = OsmId> {
        prop_oneof![
            any::<i64>().prop_map(OsmId::Way),
            any::<i64>().prop_map(OsmId::Relation)
        ]
    }

    fn record() -> impl Strategy<Value = BuildingRecord> {
        let tags = proptest::collection::btree_map("[a-z:]{1,8}", "\\PC{0,12}", 0..6);
        (
            id(),
            any::<bool>(),
            proptest::collection::vec(ring(), 1..3),
            proptest::collection::vec(ring(), 0..2),
            tags,
        )
            .prop_map(|(id, is_part, outers, inners, tags)| BuildingRecord {
                id,
                is_part,
                outers,
                inners,
                tags,
            })
    }

    fn buildings() -> impl Strategy<Value = OsmBuildings> {
        let skipped = (
            id(),
            0..SKIP_REASONS.len(),
            proptest::option::of(proptest::array::uniform4(-180.0..180.0f64)),
        )
            .prop_map(|(id, r, bounds)| Skipped {
                id,
                reason: SKIP_REASONS[r],
                bounds,
            });
        let repaired = (id(), 0..REPAIRS.len()).prop_map(|(id, w)| Repaired {
            id,
            what: REPAIRS[w],
        });
        let member_way = (
            any::<i64>(),
            any::<bool>(),
            proptest::collection::vec(any::<i64>(), 0..6),
        );
        let member_ways = (any::<i64>(), proptest::collection::vec(member_way, 0..5)).prop_map(
            |(relation, members)| MemberWays {
                relation,
                ways: members.iter().map(|m| m.0).collect(),
                inner: members.iter().map(|m| m.1).collect(),
                refs: members.into_iter().map(|m| m.2).collect(),
            },
        );
        (
            proptest::collection::vec(record(), 0..8),
            proptest::collection::vec(skipped, 0..3),
            proptest::collection::vec(repaired, 0..3),
            proptest::collection::vec(member_ways, 0..3),
        )
            .prop_map(|(buildings, skipped, repaired, member_ways)| OsmBuildings {
                buildings,
                skipped,
                repaired,
                member_ways,
            })
    }

    /// Bit for bit: `PartialEq` on `f64` would let -0.0 stand for 0.0.
    fn bits(b: &OsmBuildings) -> Vec<u64> {
        b.buildings
            .iter()
            .flat_map(|r| r.outers.iter().chain(&r.inners))
            .flat_map(|r| &r.nodes)
            .flat_map(|n| [n.lon.to_bits(), n.lat.to_bits()])
            .collect()
    }

    proptest! {
        #[test]
        fn buildings_come_back_exactly_as_packed(b in buildings()) {
            let packed = pack(&b);
            let back = unpack(&packed).unwrap();
            prop_assert_eq!(bits(&back), bits(&b));
            prop_assert_eq!(back, b);
        }

        #[test]
        fn every_cut_or_changed_byte_is_an_error_or_a_tile_never_a_panic(
            b in buildings(), cut in any::<prop::sample::Index>(), flip in any::<u8>()
        ) {
            let packed = pack(&b);
            let at = cut.index(packed.len());
            prop_assert!(unpack(&packed[..at]).is_err());
            let mut changed = packed.clone();
            changed[at] ^= flip | 1;
            let _ = unpack(&changed);
        }
    }

    #[test]
    fn another_version_is_refused_not_misread() {
        let mut packed = pack(&OsmBuildings::default());
        assert_eq!(unpack(&packed).unwrap(), OsmBuildings::default());
        packed[4] = PACKED_VERSION + 1;
        let e = unpack(&packed).unwrap_err().to_string();
        assert!(
            e.contains("version 4") && e.contains("reads versions 1 to 3"),
            "{e}"
        );
        packed[4] = 0;
        assert!(unpack(&packed).is_err());
        assert!(unpack(b"{\"elements\":[]}").is_err());
    }

    #[test]
    fn a_version_1_tile_is_read_with_no_member_ways() {
        // Version 1 ends after the repaired buildings: the same bytes less the member count.
        let b = OsmBuildings {
            repaired: vec![Repaired {
                id: OsmId::Relation(5),
                what: REPAIRS[0],
            }],
            ..Default::default()
        };
        let mut packed = pack(&b);
        assert_eq!(packed.pop(), Some(0));
        packed[4] = 1;
        assert_eq!(unpack(&packed).unwrap(), b);
        // A version 2 tile cut before its member ways is corrupt, not read as version 1.
        packed[4] = 2;
        assert!(unpack(&packed).is_err());
    }

    #[test]
    fn kept_coordinates_take_few_bytes() {
        // Four nodes 10 m apart with consecutive ids: a few bytes per node, not 24.
        let nodes = (0..4)
            .map(|i| RingNode {
                id: Some(1_000_000_000 + i),
                lon: (84_000_000 + i * 1_000) as f64 / 1e7,
                lat: 49.0,
            })
            .collect();
        let record = BuildingRecord {
            id: OsmId::Way(7),
            is_part: false,
            outers: vec![Ring { nodes }],
            inners: vec![],
            tags: [("building".to_owned(), "yes".to_owned())].into(),
        };
        let b = OsmBuildings {
            buildings: vec![record],
            ..Default::default()
        };
        let packed = pack(&b);
        // Magic and version 5; strings 1 + 9 + 4; one record: count 1, flags, id and ring counts
        // 4, the ring's length and id mode 2; the first node 5 + 4 + 5 (deltas from zero), each
        // other 1 + 2 + 1; tags 3; no skipped, no repaired, no member ways 3.
        assert_eq!(
            packed.len(),
            5 + 14 + 1 + 4 + 2 + 14 + 3 * 4 + 3 + 3,
            "{packed:?}"
        );
        assert_eq!(unpack(&packed).unwrap(), b);
    }
}

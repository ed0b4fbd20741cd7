//! From raw OSM elements to building records: closed ways and multipolygon relations tagged
//! `building=*` or `building:part=*`, with multipolygon rings joined from their member ways.
//! Whatever real data gets wrong is skipped with a reason and counted; the rest still renders.

use super::raw::{MemberKind, RawOsm, RawWay, Tags};
use foldhash::{HashMap, HashSet};
use std::fmt;

/// The OSM element a building comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum OsmId {
    Way(i64),
    Relation(i64),
}

impl fmt::Display for OsmId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OsmId::Way(id) => write!(f, "way/{id}"),
            OsmId::Relation(id) => write!(f, "relation/{id}"),
        }
    }
}

/// A point of a ring, with its node id when the source has one (used to find neighbours).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingNode {
    pub id: Option<i64>,
    pub lon: f64,
    pub lat: f64,
}

/// A closed ring, stored open: the last node is not a repeat of the first.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Ring {
    pub nodes: Vec<RingNode>,
}

impl Ring {
    /// The ring's points `[east, north]` in metres in `frame`.
    pub fn local_points(&self, frame: &crate::geo::LocalFrame) -> Vec<[f64; 2]> {
        self.nodes
            .iter()
            .map(|n| {
                let p = frame.to_local(n.lon, n.lat, 0.0);
                [p[0], p[1]]
            })
            .collect()
    }
}

/// One building or building part as OSM describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingRecord {
    pub id: OsmId,
    /// `building:part=*` rather than `building=*`.
    pub is_part: bool,
    pub outers: Vec<Ring>,
    pub inners: Vec<Ring>,
    pub tags: Tags,
}

impl BuildingRecord {
    /// Bytes the record occupies in memory, counted generously (each allocation's bookkeeping
    /// included): what a cache weighs it by.
    pub fn byte_size(&self) -> usize {
        /// A heap allocation's bookkeeping, and a B-tree entry's share of its node.
        const ALLOCATION: usize = 16;
        const TAG_ENTRY: usize = 64;
        let rings: usize = self
            .outers
            .iter()
            .chain(&self.inners)
            .map(|r| {
                std::mem::size_of::<Ring>()
                    + ALLOCATION
                    + r.nodes.capacity() * std::mem::size_of::<RingNode>()
            })
            .sum();
        let tags: usize = self
            .tags
            .iter()
            .map(|(k, v)| TAG_ENTRY + k.capacity() + v.capacity() + 2 * ALLOCATION)
            .sum();
        std::mem::size_of::<Self>() + 2 * ALLOCATION + rings + tags
    }
}

/// Why a building could not be built from the data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SkipReason {
    /// A node the way refers to is not in the data.
    MissingNodes,
    /// A member way of the relation is not in the data.
    MissingMembers,
    /// A building way whose first and last node differ.
    UnclosedWay,
    /// Member ways that do not join into closed rings.
    UnclosedRing,
    /// A ring with fewer than three distinct points.
    TooFewNodes,
    /// A multipolygon without an outer ring.
    NoOuterRing,
    /// The footprint has no area, or crosses itself beyond repair.
    DegenerateFootprint,
    /// A node lies outside longitude -180 to 180 or latitude -85.05 to 85.05 (where Web
    /// Mercator tiles end), or is not a number.
    OutOfRange,
    /// The outline spans more than [`MAX_BUILDING_EXTENT_M`] east-west or north-south: no
    /// building is that large, but a mistyped or duplicated node far away makes one so.
    TooLarge,
}

/// The largest extent (metres, east-west or north-south) a building's outline may span. The
/// largest buildings on Earth are about 1.1 km long (factory halls, airport terminals); a
/// larger outline is a data error, and would be stored with every data tile and drawn in
/// every tile it spans.
pub const MAX_BUILDING_EXTENT_M: f64 = 2_000.0;

/// The longest tag key or value kept (bytes). OpenStreetMap allows 255 characters (at most
/// 1,020 bytes of UTF-8); a longer tag is left out of the building, reported as repaired
/// (`tag_too_long`), so a hostile file cannot make every copy of a building megabytes long.
pub const MAX_TAG_BYTES: usize = 1_024;

/// Latitude where Web Mercator tiles end.
const MAX_MERCATOR_LAT: f64 = 85.051_128_78;

/// Why an outline cannot be a building's, if it cannot: a node out of range, or too large.
fn outline_problem(outers: &[Ring]) -> Option<SkipReason> {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for n in outers.iter().flat_map(|r| &r.nodes) {
        if !(n.lon.is_finite()
            && n.lat.is_finite()
            && (-180.0..=180.0).contains(&n.lon)
            && (-MAX_MERCATOR_LAT..=MAX_MERCATOR_LAT).contains(&n.lat))
        {
            return Some(SkipReason::OutOfRange);
        }
        b = [
            b[0].min(n.lon),
            b[1].min(n.lat),
            b[2].max(n.lon),
            b[3].max(n.lat),
        ];
    }
    if b[0] > b[2] {
        return None;
    }
    const M_PER_DEG: f64 = 111_320.0;
    let cos = ((b[1] + b[3]) / 2.0).to_radians().cos();
    let (east, north) = ((b[2] - b[0]) * M_PER_DEG * cos, (b[3] - b[1]) * M_PER_DEG);
    (east.max(north) > MAX_BUILDING_EXTENT_M).then_some(SkipReason::TooLarge)
}

impl SkipReason {
    /// A stable snake_case name, as used in statistics.
    pub fn name(self) -> &'static str {
        match self {
            SkipReason::MissingNodes => "missing_nodes",
            SkipReason::MissingMembers => "missing_members",
            SkipReason::UnclosedWay => "unclosed_way",
            SkipReason::UnclosedRing => "unclosed_ring",
            SkipReason::TooFewNodes => "too_few_nodes",
            SkipReason::NoOuterRing => "no_outer_ring",
            SkipReason::DegenerateFootprint => "degenerate_footprint",
            SkipReason::OutOfRange => "out_of_range",
            SkipReason::TooLarge => "too_large",
        }
    }
}

/// A building that could not be built, where it is known to be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Skipped {
    pub id: OsmId,
    pub reason: SkipReason,
    /// `[min_lon, min_lat, max_lon, max_lat]` of the nodes the data has for it, if any.
    pub bounds: Option<[f64; 4]>,
}

/// A building built with less than the data describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Repaired {
    pub id: OsmId,
    /// What was left out, e.g. `missing_inner_ring` (a courtyard whose ways or nodes are not in
    /// the data: the outline is drawn without it).
    pub what: &'static str,
}

/// The ways a multipolygon building was drawn from (every way member, in member order): what a
/// change to one of those ways must redraw, kept because the record's rings no longer say which
/// ways they were joined from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MemberWays {
    pub relation: i64,
    pub ways: Vec<i64>,
    /// For each of `ways` (same order): whether its role is `inner`, and its node ids (empty
    /// when the data had none). What a replication diff rebuilds the relation from; empty when
    /// read from a data tile packed before version 3.
    pub inner: Vec<bool>,
    pub refs: Vec<Vec<i64>>,
}

impl MemberWays {
    /// Whether the roles and node ids of every way are known (packed since version 3).
    pub fn is_complete(&self) -> bool {
        self.inner.len() == self.ways.len() && self.refs.len() == self.ways.len()
    }
}

/// The buildings of one OSM document.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OsmBuildings {
    pub buildings: Vec<BuildingRecord>,
    pub skipped: Vec<Skipped>,
    pub repaired: Vec<Repaired>,
    /// The member ways of each multipolygon in `buildings`, by relation id.
    pub member_ways: Vec<MemberWays>,
}

/// The extent of the nodes of `ways` (by id) that the data has.
fn known_bounds(
    way_ids: impl Iterator<Item = i64>,
    ways: &HashMap<i64, &RawWay>,
    nodes: &HashMap<i64, (f64, f64)>,
) -> Option<[f64; 4]> {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    let mut any = false;
    for way in way_ids.filter_map(|id| ways.get(&id)) {
        let inline = way.geometry.iter().flatten().copied();
        let resolved = way.refs.iter().filter_map(|id| nodes.get(id).copied());
        for (lon, lat) in inline.chain(resolved) {
            b = [b[0].min(lon), b[1].min(lat), b[2].max(lon), b[3].max(lat)];
            any = true;
        }
    }
    any.then_some(b)
}

fn is_yes(tags: &Tags, key: &str) -> bool {
    tags.get(key).is_some_and(|v| v != "no")
}

/// Whether the tags make a building (`Some(false)`) or a building part (`Some(true)`).
pub fn building_kind(tags: &Tags) -> Option<bool> {
    if is_yes(tags, "building") {
        Some(false)
    } else if is_yes(tags, "building:part") {
        Some(true)
    } else {
        None
    }
}

/// The points of a way, from inline geometry or by resolving node ids.
fn way_points(way: &RawWay, nodes: &HashMap<i64, (f64, f64)>) -> Result<Vec<RingNode>, SkipReason> {
    if let Some(geometry) = &way.geometry {
        if geometry.is_empty() {
            return Err(SkipReason::MissingNodes);
        }
        let ids = (way.refs.len() == geometry.len()).then_some(&way.refs);
        return Ok(geometry
            .iter()
            .enumerate()
            .map(|(i, &(lon, lat))| RingNode {
                id: ids.map(|r| r[i]),
                lon,
                lat,
            })
            .collect());
    }
    way.refs
        .iter()
        .map(|&id| {
            nodes.get(&id).map(|&(lon, lat)| RingNode {
                id: Some(id),
                lon,
                lat,
            })
        })
        .collect::<Option<Vec<_>>>()
        .ok_or(SkipReason::MissingNodes)
}

/// Two ring points are the same node: same id, or the same coordinates when ids are unknown.
fn same(a: &RingNode, b: &RingNode) -> bool {
    match (a.id, b.id) {
        (Some(x), Some(y)) => x == y,
        _ => a.lon == b.lon && a.lat == b.lat,
    }
}

/// A closed sequence of points (first == last) into a ring, or why not.
fn close_ring(mut points: Vec<RingNode>) -> Result<Ring, SkipReason> {
    if points.len() < 2 || !same(&points[0], &points[points.len() - 1]) {
        return Err(SkipReason::UnclosedWay);
    }
    points.pop();
    let distinct: HashSet<(u64, u64)> = points
        .iter()
        .map(|p| (p.lon.to_bits(), p.lat.to_bits()))
        .collect();
    if distinct.len() < 3 {
        return Err(SkipReason::TooFewNodes);
    }
    Ok(Ring { nodes: points })
}

/// Joins member ways end to end into closed rings.
fn join_rings(mut segments: Vec<Vec<RingNode>>) -> Result<Vec<Ring>, SkipReason> {
    let mut rings = Vec::new();
    while let Some(mut current) = segments.pop() {
        loop {
            if current.len() >= 4 && same(&current[0], &current[current.len() - 1]) {
                rings.push(close_ring(current).map_err(|e| match e {
                    SkipReason::UnclosedWay => SkipReason::UnclosedRing,
                    other => other,
                })?);
                break;
            }
            let end = current[current.len() - 1];
            let next = segments
                .iter()
                .position(|s| same(&s[0], &end) || same(&s[s.len() - 1], &end));
            let Some(j) = next else {
                return Err(SkipReason::UnclosedRing);
            };
            let mut seg = segments.swap_remove(j);
            if !same(&seg[0], &end) {
                seg.reverse();
            }
            current.extend_from_slice(&seg[1..]);
        }
    }
    Ok(rings)
}

/// Finds the buildings and building parts in a document.
pub fn assemble(mut raw: RawOsm) -> OsmBuildings {
    let ways: HashMap<i64, &RawWay> = raw.ways.iter().map(|w| (w.id, w)).collect();
    let mut out = OsmBuildings::default();
    // Ways that are outer members of a building multipolygon are drawn by the relation.
    let mut drawn_by_relation = HashSet::default();

    for rel in &mut raw.relations {
        if rel.tags.get("type").map(String::as_str) != Some("multipolygon") {
            continue;
        }
        let Some(is_part) = building_kind(&rel.tags) else {
            continue;
        };
        let id = OsmId::Relation(rel.id);
        // A courtyard the data lacks (ways or nodes missing, or not closing) is left out and the
        // building drawn without it; a missing outline skips the building.
        let mut inner_missing = false;
        let result = (|| {
            let mut outer = Vec::new();
            let mut inner = Vec::new();
            for m in rel.members.iter().filter(|m| m.kind == MemberKind::Way) {
                let is_inner = m.role == "inner";
                let points = match (&m.geometry, ways.get(&m.id)) {
                    (Some(g), _) if !g.is_empty() => Ok(g
                        .iter()
                        .map(|&(lon, lat)| RingNode { id: None, lon, lat })
                        .collect()),
                    (_, Some(way)) => way_points(way, &raw.nodes),
                    (Some(_), None) => Err(SkipReason::MissingNodes),
                    (None, None) => Err(SkipReason::MissingMembers),
                };
                let points = match points {
                    Ok(p) if p.len() >= 2 => p,
                    Ok(_) if is_inner => {
                        inner_missing = true;
                        continue;
                    }
                    Ok(_) => return Err(SkipReason::TooFewNodes),
                    Err(_) if is_inner => {
                        inner_missing = true;
                        continue;
                    }
                    Err(reason) => return Err(reason),
                };
                if is_inner {
                    inner.push(points);
                } else {
                    outer.push(points);
                    drawn_by_relation.insert(m.id);
                }
            }
            let outers = join_rings(outer)?;
            if outers.is_empty() {
                return Err(SkipReason::NoOuterRing);
            }
            let inners = join_rings(inner).unwrap_or_else(|_| {
                inner_missing = true;
                Vec::new()
            });
            Ok((outers, inners))
        })();
        match result {
            Ok((outers, inners)) => {
                if inner_missing {
                    out.repaired.push(Repaired {
                        id,
                        what: "missing_inner_ring",
                    });
                }
                let way_members = || rel.members.iter().filter(|m| m.kind == MemberKind::Way);
                out.member_ways.push(MemberWays {
                    relation: rel.id,
                    ways: way_members().map(|m| m.id).collect(),
                    inner: way_members().map(|m| m.role == "inner").collect(),
                    refs: way_members()
                        .map(|m| ways.get(&m.id).map(|w| w.refs.clone()).unwrap_or_default())
                        .collect(),
                });
                out.buildings.push(BuildingRecord {
                    id,
                    is_part,
                    outers,
                    inners,
                    // Each relation is read once: its tags move to the record.
                    tags: std::mem::take(&mut rel.tags),
                });
            }
            Err(reason) => {
                let members = rel
                    .members
                    .iter()
                    .filter(|m| m.kind == MemberKind::Way)
                    .map(|m| m.id);
                let bounds = known_bounds(members, &ways, &raw.nodes);
                out.skipped.push(Skipped { id, reason, bounds });
            }
        }
    }

    // Rings first (relations may still look ways up), then each way's tags move to its record.
    let mut rings = Vec::new();
    for (i, way) in raw.ways.iter().enumerate() {
        let Some(is_part) = building_kind(&way.tags) else {
            continue;
        };
        if drawn_by_relation.contains(&way.id) {
            continue;
        }
        let id = OsmId::Way(way.id);
        match way_points(way, &raw.nodes).and_then(close_ring) {
            Ok(ring) => rings.push((i, is_part, ring)),
            Err(reason) => {
                let bounds = known_bounds(std::iter::once(way.id), &ways, &raw.nodes);
                out.skipped.push(Skipped { id, reason, bounds });
            }
        }
    }
    drop(ways);
    for (i, is_part, ring) in rings {
        let way = &mut raw.ways[i];
        out.buildings.push(BuildingRecord {
            id: OsmId::Way(way.id),
            is_part,
            outers: vec![ring],
            inners: Vec::new(),
            tags: std::mem::take(&mut way.tags),
        });
    }
    // Outlines no building has: skipped with where they reach.
    let mut kept = Vec::with_capacity(out.buildings.len());
    for mut b in std::mem::take(&mut out.buildings) {
        match outline_problem(&b.outers) {
            None => {
                let tags = b.tags.len();
                b.tags
                    .retain(|k, v| k.len() <= MAX_TAG_BYTES && v.len() <= MAX_TAG_BYTES);
                if b.tags.len() < tags {
                    out.repaired.push(Repaired {
                        id: b.id,
                        what: "tag_too_long",
                    });
                }
                kept.push(b);
            }
            Some(reason) => {
                let r = crate::building::cluster::record_bounds(&b);
                let bounds = r.iter().all(|v| v.is_finite()).then_some(r);
                out.skipped.push(Skipped {
                    id: b.id,
                    reason,
                    bounds,
                });
            }
        }
    }
    out.buildings = kept;
    out.buildings.sort_by_key(|b| b.id);
    let drawn: HashSet<i64> = out
        .buildings
        .iter()
        .filter_map(|b| match b.id {
            OsmId::Relation(id) => Some(id),
            OsmId::Way(_) => None,
        })
        .collect();
    out.member_ways.retain(|m| drawn.contains(&m.relation));
    out.member_ways.sort_by_key(|m| m.relation);
    out.skipped.sort_by_key(|s| s.id);
    out.repaired.sort_by_key(|r| r.id);
    out
}

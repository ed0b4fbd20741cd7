//! Clusters: the buildings that must be generated together (docs/method.md section 7). Buildings
//! that share an OSM node touch, so their hidden walls are removed together; a `building:part`
//! inside a `building` outline is cut out of it. A cluster is never split between tiles.

use crate::geo::GeoBbox;
use crate::osm::{BuildingRecord, RingNode};
use crate::union_find::UnionFind;
use foldhash::HashMap;

/// The identity of a node for adjacency: its id, or its exact coordinates when it has none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NodeRef {
    Id(i64),
    At(u64, u64),
}

impl NodeRef {
    pub fn of(n: &RingNode) -> Self {
        match n.id {
            Some(id) => NodeRef::Id(id),
            None => NodeRef::At(n.lon.to_bits(), n.lat.to_bits()),
        }
    }
}

/// The average of a ring's nodes (lon, lat).
pub fn ring_centre(nodes: &[RingNode]) -> (f64, f64) {
    let n = nodes.len().max(1) as f64;
    let (x, y) = nodes
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.lon, y + p.lat));
    (x / n, y / n)
}

/// Whether (lon, lat) lies inside a ring (crossing number, in degrees).
pub fn ring_contains(nodes: &[RingNode], (x, y): (f64, f64)) -> bool {
    let n = nodes.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (&nodes[i], &nodes[j]);
        if (a.lat > y) != (b.lat > y) && x < (b.lon - a.lon) * (y - a.lat) / (b.lat - a.lat) + a.lon
        {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Whether `part` stands inside `outline`: the centre of its first outer ring lies in one of the
/// outline's outer rings.
pub fn part_of(part: &BuildingRecord, outline: &BuildingRecord) -> bool {
    part.outers.first().is_some_and(|r| {
        let c = ring_centre(&r.nodes);
        outline.outers.iter().any(|o| ring_contains(&o.nodes, c))
    })
}

/// The bounding box (min lon, min lat, max lon, max lat) of a record's outer rings.
pub fn record_bounds(b: &BuildingRecord) -> [f64; 4] {
    b.outers.iter().flat_map(|r| &r.nodes).fold(
        [f64::MAX, f64::MAX, f64::MIN, f64::MIN],
        |[a, b, c, d], p| [a.min(p.lon), b.min(p.lat), c.max(p.lon), d.max(p.lat)],
    )
}

/// The box around every outline point of `records`, or `None` when they have none.
pub fn records_extent(records: &[BuildingRecord]) -> Option<GeoBbox> {
    let [a, b, c, d] = records.iter().map(record_bounds).fold(
        [f64::MAX, f64::MAX, f64::MIN, f64::MIN],
        |[a, b, c, d], [e, f, g, h]| [a.min(e), b.min(f), c.max(g), d.max(h)],
    );
    GeoBbox::new(a, b, c, d).ok()
}

/// Groups records into clusters; each cluster lists record indices in ascending order, and the
/// clusters are ordered by their first record.
pub fn clusters<R: std::borrow::Borrow<BuildingRecord>>(records: &[R]) -> Vec<Vec<usize>> {
    let mut uf = UnionFind::new(records.len());
    let mut first_with: HashMap<NodeRef, usize> = HashMap::default();
    for (i, b) in records.iter().map(R::borrow).enumerate() {
        for node in b.outers.iter().chain(&b.inners).flat_map(|r| &r.nodes) {
            let j = *first_with.entry(NodeRef::of(node)).or_insert(i);
            uf.union(i, j);
        }
    }
    // Parts join the outline they stand in, found through a coarse grid of outline boxes.
    const CELL: f64 = 0.002;
    let cell = |lon: f64, lat: f64| ((lon / CELL).floor() as i64, (lat / CELL).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::default();
    for (i, b) in records
        .iter()
        .map(R::borrow)
        .enumerate()
        .filter(|(_, b)| !b.is_part)
    {
        let [x0, y0, x1, y1] = record_bounds(b);
        let ((cx0, cy0), (cx1, cy1)) = (cell(x0, y0), cell(x1, y1));
        if (cx1 - cx0 + 1) * (cy1 - cy0 + 1) > 10_000 {
            continue;
        }
        for cx in cx0..=cx1 {
            for cy in cy0..=cy1 {
                grid.entry((cx, cy)).or_default().push(i);
            }
        }
    }
    for (i, p) in records
        .iter()
        .map(R::borrow)
        .enumerate()
        .filter(|(_, b)| b.is_part)
    {
        let Some(ring) = p.outers.first() else {
            continue;
        };
        let (x, y) = ring_centre(&ring.nodes);
        if let Some(candidates) = grid.get(&cell(x, y)) {
            for &o in candidates {
                if part_of(p, records[o].borrow()) {
                    uf.union(i, o);
                }
            }
        }
    }
    let mut by_root: HashMap<usize, Vec<usize>> = HashMap::default();
    for i in 0..records.len() {
        let root = uf.find(i);
        by_root.entry(root).or_default().push(i);
    }
    let mut out: Vec<Vec<usize>> = by_root.into_values().collect();
    out.sort_by_key(|c| c[0]);
    out
}

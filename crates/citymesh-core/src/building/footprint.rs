//! A building's footprint in the local frame: one outer ring and its courtyards, cleaned of what
//! real data gets wrong (repeated nodes, spikes, wrong winding), or refused when it has no area or
//! crosses itself.
//!
//! Every point keeps a [`NodeKey`], so two buildings that share OSM nodes can find the walls they
//! share (docs/method.md section 7).
use super::length::planar_length;

use super::sweep::{any_overlapping_pair, segment_bounds};

/// Points closer than this (metres) are one point.
pub const MERGE_DISTANCE: f64 = 1e-3;

/// Footprints with less area (m²) are not buildings.
pub const MIN_AREA: f64 = 0.05;

/// Most vertices a ring may have. OpenStreetMap caps a way at 2,000 nodes; an outline over twice
/// that is refused (`too_many_nodes`) rather than checked at a cost that grows with its square
/// in the worst case.
pub const MAX_RING_VERTICES: usize = 4_000;

/// Most courtyards (holes) one footprint may have: checking holes against each other, and a
/// point against the holes, grows with their number, so a building with more is refused
/// (`too_many_holes`) and the rest of its scene renders. OpenStreetMap's most complex buildings
/// have a few dozen.
pub const MAX_HOLES: usize = 256;

/// Most vertices one footprint may have, its outline and courtyards together.
pub const MAX_FOOTPRINT_VERTICES: usize = 16_000;

/// Rings up to this many vertices are checked pair by pair (cheaper than sorting for them).
const SMALL_RING: usize = 48;

/// What identifies a footprint point across buildings: its OSM node id, or where the source gives
/// no ids, its exact projected coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NodeKey {
    Osm(i64),
    At(u64, u64),
}

impl NodeKey {
    /// The key of a point without an OSM id.
    pub fn at(p: [f64; 2]) -> Self {
        NodeKey::At(p[0].to_bits(), p[1].to_bits())
    }
}

/// A closed ring stored open (the first point is not repeated at the end).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FootprintRing {
    pub points: Vec<[f64; 2]>,
    pub keys: Vec<NodeKey>,
}

/// Why a footprint cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FootprintError {
    #[error("the outline has fewer than three distinct points")]
    TooFewPoints,
    #[error("the outline has no area")]
    NoArea,
    #[error("the outline crosses itself")]
    SelfIntersecting,
    #[error("a coordinate is not a finite number")]
    NotFinite,
    #[error(
        "a ring has more than {MAX_RING_VERTICES} vertices, or the footprint more than {MAX_FOOTPRINT_VERTICES}"
    )]
    TooManyVertices,
    #[error("the footprint has more than {MAX_HOLES} courtyards")]
    TooManyHoles,
}

/// A cleaned footprint: the outer ring counter-clockwise, courtyards clockwise, in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct Footprint {
    pub outer: FootprintRing,
    pub holes: Vec<FootprintRing>,
}

impl FootprintRing {
    pub fn new(points: Vec<[f64; 2]>, keys: Vec<NodeKey>) -> Self {
        debug_assert_eq!(points.len(), keys.len());
        Self { points, keys }
    }

    /// A ring whose keys are its coordinates.
    pub fn from_points(points: Vec<[f64; 2]>) -> Self {
        let keys = points.iter().map(|&p| NodeKey::at(p)).collect();
        Self { points, keys }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The signed area: positive when counter-clockwise.
    pub fn signed_area(&self) -> f64 {
        signed_area(&self.points)
    }

    /// Drops repeated points and spikes (A, B, A) until none are left.
    fn clean(&mut self) {
        loop {
            let before = self.points.len();
            self.drop_repeats();
            self.drop_spikes();
            if self.points.len() == before || self.points.len() < 3 {
                return;
            }
        }
    }

    fn drop_repeats(&mut self) {
        let n = self.points.len();
        if n == 0 {
            return;
        }
        let mut keep = vec![true; n];
        let mut last = 0;
        for (i, k) in keep.iter_mut().enumerate().skip(1) {
            if close(self.points[i], self.points[last]) {
                *k = false;
            } else {
                last = i;
            }
        }
        // The ring closes on itself: the tail may repeat the first point.
        while last > 0 && close(self.points[last], self.points[0]) {
            keep[last] = false;
            last = (0..last).rev().find(|&i| keep[i]).unwrap_or(0);
        }
        self.retain(&keep);
    }

    /// Removes points whose two neighbours coincide: the ring goes out and straight back.
    fn drop_spikes(&mut self) {
        let n = self.points.len();
        if n < 3 {
            return;
        }
        let mut keep = vec![true; n];
        for i in 0..n {
            let prev = self.points[(i + n - 1) % n];
            let next = self.points[(i + 1) % n];
            if keep[(i + n - 1) % n] && close(prev, next) {
                keep[i] = false;
            }
        }
        self.retain(&keep);
    }

    fn retain(&mut self, keep: &[bool]) {
        let mut k = keep.iter();
        self.points.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        self.keys.retain(|_| *k.next().unwrap_or(&true));
    }

    fn reverse(&mut self) {
        self.points.reverse();
        self.keys.reverse();
    }

    /// Whether two edges of the ring cross or touch anywhere but at their shared end.
    fn self_intersects(&self) -> bool {
        let n = self.points.len();
        let edge = |i: usize| (self.points[i], self.points[(i + 1) % n]);
        let touch = |i: usize, j: usize| {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            segments_touch(edge(i), edge(j), adjacent)
        };
        // Most outlines are small: all pairs without allocating; long rings take the sweep.
        if n <= SMALL_RING {
            return (0..n).any(|i| (i + 1..n).any(|j| touch(i, j)));
        }
        let boxes: Vec<_> = (0..n)
            .map(|i| {
                let (a, b) = edge(i);
                segment_bounds(a, b)
            })
            .collect();
        any_overlapping_pair(&boxes, touch)
    }
}

impl Footprint {
    /// Cleans and checks the rings. Courtyards that fall outside the outer ring, cross it or
    /// another courtyard are dropped (the building keeps its outline).
    pub fn new(outer: FootprintRing, holes: Vec<FootprintRing>) -> Result<Self, FootprintError> {
        Self::with_courtyards_apart(outer, holes).map(|(f, _)| f)
    }

    /// [`Footprint::new`], answering too the courtyards it could not keep as holes though they
    /// are rings (cleaned, counter-clockwise): those touching or crossing the outer ring or a
    /// courtyard kept, or not inside. They are cut out of the footprint by a boolean difference
    /// (`pieces::cut_out`), which unites courtyards that share an edge.
    pub fn with_courtyards_apart(
        mut outer: FootprintRing,
        holes: Vec<FootprintRing>,
    ) -> Result<(Self, Vec<FootprintRing>), FootprintError> {
        if outer
            .points
            .iter()
            .chain(holes.iter().flat_map(|h| &h.points))
            .any(|p| !p[0].is_finite() || !p[1].is_finite())
        {
            return Err(FootprintError::NotFinite);
        }
        if holes.len() > MAX_HOLES {
            return Err(FootprintError::TooManyHoles);
        }
        if std::iter::once(&outer)
            .chain(&holes)
            .any(|r| r.points.len() > MAX_RING_VERTICES)
            || outer.points.len() + holes.iter().map(|h| h.points.len()).sum::<usize>()
                > MAX_FOOTPRINT_VERTICES
        {
            return Err(FootprintError::TooManyVertices);
        }
        outer.clean();
        if outer.len() < 3 {
            return Err(FootprintError::TooFewPoints);
        }
        let area = outer.signed_area();
        if area.abs() < MIN_AREA {
            return Err(FootprintError::NoArea);
        }
        if area < 0.0 {
            outer.reverse();
        }
        if outer.self_intersects() {
            return Err(FootprintError::SelfIntersecting);
        }
        let mut kept: Vec<FootprintRing> = Vec::new();
        let mut apart: Vec<FootprintRing> = Vec::new();
        for mut hole in holes {
            hole.clean();
            if hole.len() < 3 || hole.signed_area().abs() < MIN_AREA || hole.self_intersects() {
                continue;
            }
            if hole.signed_area() > 0.0 {
                hole.reverse();
            }
            let inside = hole
                .points
                .iter()
                .all(|&p| strictly_inside(&outer.points, p));
            let crosses = |other: &FootprintRing| rings_touch(&hole, other);
            if inside && !crosses(&outer) && !kept.iter().any(crosses) {
                kept.push(hole);
            } else {
                hole.reverse();
                apart.push(hole);
            }
        }
        Ok((Self { outer, holes: kept }, apart))
    }

    /// All rings: the outer first, then the courtyards.
    pub fn rings(&self) -> impl Iterator<Item = &FootprintRing> {
        std::iter::once(&self.outer).chain(&self.holes)
    }

    /// Whether `p` lies inside (courtyards are outside).
    pub fn contains(&self, p: [f64; 2]) -> bool {
        inside(&self.outer.points, p) && !self.holes.iter().any(|h| inside(&h.points, p))
    }

    /// The distance from `p` to the nearest ring edge.
    pub fn distance_to_boundary(&self, p: [f64; 2]) -> f64 {
        self.rings()
            .flat_map(|r| {
                let n = r.len();
                (0..n).map(move |i| segment_distance(p, r.points[i], r.points[(i + 1) % n]))
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Area in m² (courtyards subtracted).
    pub fn area(&self) -> f64 {
        self.outer.signed_area()
            + self
                .holes
                .iter()
                .map(FootprintRing::signed_area)
                .sum::<f64>()
    }
}

/// Whether two points are one.
#[inline]
fn close(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() <= MERGE_DISTANCE && (a[1] - b[1]).abs() <= MERGE_DISTANCE
}

/// The signed area of an open ring (shoelace formula).
pub fn signed_area(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    if n < 3 {
        return 0.0;
    }
    // Relative to the first point, for precision far from the frame origin.
    let o = points[0];
    let mut sum = 0.0;
    for i in 1..n - 1 {
        let (p, q) = (points[i], points[i + 1]);
        sum += (p[0] - o[0]) * (q[1] - o[1]) - (q[0] - o[0]) * (p[1] - o[1]);
    }
    sum / 2.0
}

/// Crossing-number test; points on the boundary may answer either way.
pub fn inside(ring: &[[f64; 2]], p: [f64; 2]) -> bool {
    let n = ring.len();
    let mut c = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (ring[i], ring[j]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0];
            if p[0] < x {
                c = !c;
            }
        }
        j = i;
    }
    c
}

fn strictly_inside(ring: &[[f64; 2]], p: [f64; 2]) -> bool {
    let n = ring.len();
    inside(ring, p)
        && (0..n).all(|i| segment_distance(p, ring[i], ring[(i + 1) % n]) > MERGE_DISTANCE)
}

/// The distance from `p` to the segment `a`-`b`.
pub fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len2 = d[0] * d[0] + d[1] * d[1];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    planar_length(p[0] - a[0] - t * d[0], p[1] - a[1] - t * d[1])
}

/// Orientation of `c` relative to the line `a`-`b`: positive to the left.
#[inline]
pub fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether two segments share a point. Adjacent edges share their common end, which is allowed,
/// unless they also overlap (the ring doubles back).
fn segments_touch(
    (a, b): ([f64; 2], [f64; 2]),
    (c, d): ([f64; 2], [f64; 2]),
    adjacent: bool,
) -> bool {
    let (lo1, hi1) = (
        [a[0].min(b[0]), a[1].min(b[1])],
        [a[0].max(b[0]), a[1].max(b[1])],
    );
    let (lo2, hi2) = (
        [c[0].min(d[0]), c[1].min(d[1])],
        [c[0].max(d[0]), c[1].max(d[1])],
    );
    if lo1[0] > hi2[0] || lo2[0] > hi1[0] || lo1[1] > hi2[1] || lo2[1] > hi1[1] {
        return false;
    }
    if adjacent {
        // They share an end; they only touch elsewhere if they are collinear and overlap.
        let shared_is_bc = close(b, c);
        let (p, q, r) = if shared_is_bc { (a, b, d) } else { (c, d, b) };
        // p-q and q-r: overlapping means r lies back along q-p.
        let turn = orient(p, q, r);
        let back = (p[0] - q[0]) * (r[0] - q[0]) + (p[1] - q[1]) * (r[1] - q[1]);
        let len =
            (planar_length(p[0] - q[0], p[1] - q[1])) * (planar_length(r[0] - q[0], r[1] - q[1]));
        return turn.abs() <= 1e-12 * len && back > 0.0;
    }
    let d1 = orient(c, d, a);
    let d2 = orient(c, d, b);
    let d3 = orient(a, b, c);
    let d4 = orient(a, b, d);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    // Touching: an end of one lies on the other.
    segment_distance(a, c, d) <= MERGE_DISTANCE
        || segment_distance(b, c, d) <= MERGE_DISTANCE
        || segment_distance(c, a, b) <= MERGE_DISTANCE
        || segment_distance(d, a, b) <= MERGE_DISTANCE
}

fn rings_touch(x: &FootprintRing, y: &FootprintRing) -> bool {
    let (n, m) = (x.len(), y.len());
    let x_edge = |i: usize| (x.points[i], x.points[(i + 1) % n]);
    let y_edge = |j: usize| (y.points[j], y.points[(j + 1) % m]);
    if n * m <= SMALL_RING * SMALL_RING {
        return (0..n).any(|i| (0..m).any(|j| segments_touch(x_edge(i), y_edge(j), false)));
    }
    let boxes: Vec<_> = (0..n)
        .map(x_edge)
        .chain((0..m).map(y_edge))
        .map(|(a, b)| segment_bounds(a, b))
        .collect();
    // Only pairs with one edge from each ring.
    any_overlapping_pair(&boxes, |i, j| {
        i < n && j >= n && segments_touch(x_edge(i), y_edge(j - n), false)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_footprint_with_more_courtyards_than_the_cap_is_refused_whole() {
        let outer = FootprintRing::from_points(vec![
            [0.0, 0.0],
            [400.0, 0.0],
            [400.0, 400.0],
            [0.0, 400.0],
        ]);
        let holes = |n: usize| -> Vec<FootprintRing> {
            (0..n)
                .map(|k| {
                    let (x, y) = ((k % 20) as f64 * 20.0 + 2.0, (k / 20) as f64 * 20.0 + 2.0);
                    FootprintRing::from_points(vec![
                        [x, y],
                        [x, y + 5.0],
                        [x + 5.0, y + 5.0],
                        [x + 5.0, y],
                    ])
                })
                .collect()
        };
        let kept = Footprint::new(outer.clone(), holes(MAX_HOLES)).unwrap();
        assert_eq!(kept.holes.len(), MAX_HOLES);
        assert_eq!(
            Footprint::new(outer, holes(MAX_HOLES + 1)),
            Err(FootprintError::TooManyHoles)
        );
    }

    fn ring(points: &[[f64; 2]]) -> FootprintRing {
        FootprintRing::from_points(points.to_vec())
    }

    #[test]
    fn cleans_repeats_spikes_and_winding() {
        let f = Footprint::new(
            ring(&[
                [0.0, 0.0],
                [0.0, 5.0],
                [0.0, 5.0],
                [10.0, 5.0],
                [12.0, 5.0],
                [10.0, 5.0],
                [10.0, 0.0],
                [0.0, 0.0],
            ]),
            vec![],
        )
        .unwrap();
        assert_eq!(
            f.outer.points,
            vec![[10.0, 0.0], [10.0, 5.0], [0.0, 5.0], [0.0, 0.0]]
        );
        assert!((f.area() - 50.0).abs() < 1e-12);
    }

    #[test]
    fn refuses_what_is_not_a_footprint() {
        let bow_tie = ring(&[[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 4.0]]);
        assert_eq!(
            Footprint::new(bow_tie, vec![]),
            Err(FootprintError::SelfIntersecting)
        );
        let line = ring(&[[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]);
        assert_eq!(Footprint::new(line, vec![]), Err(FootprintError::NoArea));
        let two = ring(&[[0.0, 0.0], [10.0, 0.0], [0.0, 0.0]]);
        assert_eq!(
            Footprint::new(two, vec![]),
            Err(FootprintError::TooFewPoints)
        );
    }

    #[test]
    fn keeps_courtyards_inside_and_drops_others() {
        let outer = ring(&[[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]]);
        let court = ring(&[[5.0, 5.0], [15.0, 5.0], [15.0, 15.0], [5.0, 15.0]]);
        let outside = ring(&[[30.0, 5.0], [35.0, 5.0], [35.0, 15.0]]);
        let f = Footprint::new(outer, vec![court, outside]).unwrap();
        assert_eq!(f.holes.len(), 1);
        assert!(f.holes[0].signed_area() < 0.0);
        assert!((f.area() - 300.0).abs() < 1e-9);
        assert!(f.contains([2.0, 2.0]) && !f.contains([10.0, 10.0]));
    }
}

//! The straight skeleton of a footprint with courtyards (docs/method.md section 6.7): every edge
//! of the outline moves inwards at unit speed, parallel to itself; where the moving edges meet
//! they trace the skeleton's arcs, and each edge sweeps one face. A hipped roof of one pitch is
//! that sweep lifted by the time each point is reached, so every face is planar and rises from
//! its own edge.
//!
//! The wavefront is simulated event by event: at each step every possible next event is
//! measured on the current wavefront (an edge shrinking to nothing, or a reflex vertex running
//! into an edge and splitting the wavefront, or joining a courtyard's wavefront to the outer one)
//! and the earliest is applied. Recomputing all events at each step costs O(n²) per event, O(n³)
//! per footprint; [`MAX_SKELETON_VERTICES`] bounds it, and footprints over it keep the virtual
//! rectangle. Two edges that become adjacent while parallel and facing each other (the end of a
//! wing, seen from its ridge) meet along their whole common stretch at once: the ridge is laid
//! at that moment rather than simulated.
//!
//! The result is checked before use: every face closes, the faces' areas sum to the
//! footprint's, and every node lies on the plane of each face it bounds. A footprint that fails
//! (numerically unlucky coincidences of events) gets [`SkeletonError::Inconsistent`], and its
//! roof keeps the virtual rectangle.
//!
//! Here: the skeleton, its check and the shaking; [`wavefront`] simulates the events, `faces`
//! chains each edge's face from the arcs.

use super::length::planar_length;
use vector::{add, cross, dot, sub};
use wavefront::Wavefront;

mod faces;
#[cfg(test)]
mod tests;
mod vector;
mod wavefront;

/// Most vertices (outline and courtyards together) a footprint may have for its skeleton: the
/// worst case measured (a 128-pointed star, all its events at once, shaken) takes 7.3 ms here;
/// real outlines of this size take well under 1 ms.
pub const MAX_SKELETON_VERTICES: usize = 128;

/// How far (m) an outline's points are moved, at most, when its exact skeleton cannot be
/// simulated ([`Skeleton::of`]).
pub const SHAKE: f64 = 1e-4;

/// Shaken outlines tried before giving up.
const SHAKE_TRIES: u64 = 3;

/// A fixed pseudo-random offset of at most [`SHAKE`] for point `i` of ring `r`: the same on
/// every run, so the same outline always gets the same roof.
fn shake(seed: u64, r: usize, i: usize) -> [f64; 2] {
    let mut x = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((r as u64) << 32 | i as u64);
    let mut next = || {
        // splitmix64
        x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = x;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    [SHAKE * next(), SHAKE * next()]
}

/// Why a footprint has no skeleton.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SkeletonError {
    #[error("the footprint has more vertices than the skeleton takes")]
    TooManyVertices,
    #[error("the outline doubles back on itself (a spike)")]
    Spike,
    #[error("the wavefront did not resolve into closed planar faces")]
    Inconsistent,
}

/// A point of the skeleton: where it stands, and when the wavefront reaches it (its distance
/// from the nearest edge whose face it bounds, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonNode {
    pub at: [f64; 2],
    pub time: f64,
}

/// One edge of the input as a line: a point on it, its unit direction, and the unit normal
/// pointing into the footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeLine {
    pub a: [f64; 2],
    pub b: [f64; 2],
    pub u: [f64; 2],
    pub n: [f64; 2],
}

impl EdgeLine {
    fn new(a: [f64; 2], b: [f64; 2]) -> Self {
        let d = sub(b, a);
        let len = planar_length(d[0], d[1]);
        let u = [d[0] / len, d[1] / len];
        Self {
            a,
            b,
            u,
            n: [-u[1], u[0]],
        }
    }

    /// How far `p` lies inside the edge's line: the time the wavefront of this edge reaches it.
    #[inline]
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        dot(sub(p, self.a), self.n)
    }
}

/// The straight skeleton: nodes, the face each input edge sweeps, and the arcs between faces.
#[derive(Debug, Clone)]
pub struct Skeleton {
    pub nodes: Vec<SkeletonNode>,
    /// One line per input edge: the outer ring's edges first, then each courtyard's, each ring
    /// in its order (edge `i` runs from point `i` to point `i + 1`).
    pub edges: Vec<EdgeLine>,
    /// The face each edge sweeps: node indices counter-clockwise, starting with the edge's own
    /// two ends.
    pub faces: Vec<Vec<usize>>,
    /// Where two faces meet: the two nodes and the two edges whose faces it divides.
    pub arcs: Vec<Arc>,
}

/// A skeleton arc: from node to node, between the faces of two edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arc {
    pub nodes: [usize; 2],
    pub faces: [usize; 2],
}

impl Skeleton {
    /// The skeleton of a footprint: `rings[0]` is the outline, counter-clockwise; the others are
    /// courtyards, clockwise (the footprint's interior on the left of every edge). Points must be
    /// distinct and the rings simple and disjoint, as [`super::footprint::Footprint`] makes them.
    ///
    /// Many events at one point and moment (the reflex corners of a regular star all reaching
    /// its centre together) can defeat the event-by-event simulation; then the outline is
    /// shaken by at most [`SHAKE`] metres, which parts the events, and the skeleton of the
    /// shaken outline is used with its outline points put back where they were (its inner nodes
    /// stay within about [`SHAKE`] of where the exact skeleton has them).
    pub fn of(rings: &[&[[f64; 2]]]) -> Result<Self, SkeletonError> {
        match Self::exact(rings) {
            Err(SkeletonError::Inconsistent) => {}
            done => return done,
        }
        let mut last = SkeletonError::Inconsistent;
        for seed in 1..=SHAKE_TRIES {
            let shaken: Vec<Vec<[f64; 2]>> = rings
                .iter()
                .enumerate()
                .map(|(r, ring)| {
                    ring.iter()
                        .enumerate()
                        .map(|(i, p)| {
                            let [dx, dy] = shake(seed, r, i);
                            [p[0] + dx, p[1] + dy]
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[[f64; 2]]> = shaken.iter().map(Vec::as_slice).collect();
            match Self::exact(&refs) {
                Ok(mut skeleton) => {
                    skeleton.restore_outline(rings);
                    return Ok(skeleton);
                }
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    /// The skeleton by simulation alone, without shaking.
    fn exact(rings: &[&[[f64; 2]]]) -> Result<Self, SkeletonError> {
        let total: usize = rings.iter().map(|r| r.len()).sum();
        if total > MAX_SKELETON_VERTICES {
            return Err(SkeletonError::TooManyVertices);
        }
        if rings.is_empty() || rings.iter().any(|r| r.len() < 3) {
            return Err(SkeletonError::Inconsistent);
        }
        // Work near the origin, for precision far from the frame's.
        let origin = rings[0][0];
        let mut wave = Wavefront::start(rings, origin)?;
        wave.run(total)?;
        let mut skeleton = wave.into_skeleton(total)?;
        for node in &mut skeleton.nodes {
            node.at = add(node.at, origin);
        }
        skeleton.restore_outline(rings);
        skeleton.check(rings)?;
        Ok(skeleton)
    }

    /// The outline's own points and lines exactly as given (the simulation ran near the origin,
    /// or on a shaken outline).
    fn restore_outline(&mut self, rings: &[&[[f64; 2]]]) {
        let mut k = 0;
        for ring in rings {
            for (i, p) in ring.iter().enumerate() {
                self.nodes[k + i].at = *p;
                self.edges[k + i] = EdgeLine::new(*p, ring[(i + 1) % ring.len()]);
            }
            k += ring.len();
        }
    }

    /// The latest time any node is reached: the roof's run from eaves to top.
    pub fn max_time(&self) -> f64 {
        self.nodes.iter().map(|n| n.time).fold(0.0, f64::max)
    }

    /// The face polygon of edge `e` in metres.
    pub fn face_points(&self, e: usize) -> Vec<[f64; 2]> {
        self.faces[e].iter().map(|&k| self.nodes[k].at).collect()
    }

    /// What every skeleton promises: the faces' areas sum to the footprint's, no face turns
    /// clockwise, and each node lies on the plane of every face it bounds.
    fn check(&self, rings: &[&[[f64; 2]]]) -> Result<(), SkeletonError> {
        let area: f64 = rings.iter().map(|r| twice_area(r)).sum::<f64>() / 2.0;
        let scale = rings[0]
            .iter()
            .map(|p| planar_length(p[0] - rings[0][0][0], p[1] - rings[0][0][1]))
            .fold(1.0, f64::max);
        let mut sum = 0.0;
        for (e, face) in self.faces.iter().enumerate() {
            let a = twice_area(&self.face_points(e)) / 2.0;
            if a < -1e-9 * scale * scale {
                return Err(SkeletonError::Inconsistent);
            }
            sum += a;
            for &k in face {
                let node = self.nodes[k];
                if (self.edges[e].distance(node.at) - node.time).abs() > 1e-6 * scale {
                    return Err(SkeletonError::Inconsistent);
                }
            }
        }
        if (sum - area).abs() > 1e-7 * area.max(1.0) {
            return Err(SkeletonError::Inconsistent);
        }
        Ok(())
    }
}

fn twice_area(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    let o = points[0];
    (1..n.saturating_sub(1))
        .map(|i| cross(sub(points[i], o), sub(points[i + 1], o)))
        .sum()
}

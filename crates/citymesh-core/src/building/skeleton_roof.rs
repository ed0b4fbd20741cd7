//! Hipped, gabled and pyramidal roofs over any footprint, courtyards included, from its straight
//! skeleton (docs/method.md section 6.7): each face rises from its own edge at one pitch, so
//! ridges follow the wings of an L, T or U and valleys run into their inner corners. A gabled
//! roof is the hipped one with each hip end that closes a wing (a triangle between two parallel
//! sides) turned upright into a gable: its top is moved along the ridge onto the end wall.
//!
//! The roof's rise at a point is the time the skeleton's wavefront reaches it (its distance
//! from the edge whose face holds it); the descending level function of the other shapes is
//! `1 - rise / run`, with the run the latest time of all.

use super::footprint::{Footprint, inside, segment_distance};
use super::length::planar_length;
use super::straight_skeleton::{EdgeLine, Skeleton, SkeletonError};

/// The two sides of a wing end are taken as parallel (and the end turned into a gable) when
/// they are within this angle (degrees) of it.
pub const GABLE_SIDES_WITHIN_DEGREES: f64 = 10.0;

/// One plane of the roof: where it lies in plan and the edge it rises from.
#[derive(Debug, Clone)]
struct RoofFace {
    points: Vec<[f64; 2]>,
    edge: EdgeLine,
    /// `[min_x, min_y, max_x, max_y]` of `points`.
    bounds: [f64; 4],
}

/// A roof over a footprint's straight skeleton.
#[derive(Debug, Clone)]
pub struct SkeletonRoof {
    faces: Vec<RoofFace>,
    run: f64,
    segments: Vec<[[f64; 2]; 2]>,
}

impl SkeletonRoof {
    /// The hipped roof (every face one pitch) over `footprint`.
    pub fn hipped(footprint: &Footprint) -> Result<Self, SkeletonError> {
        Ok(Self::from_skeleton(skeleton_of(footprint)?, &[]))
    }

    /// The gabled roof over `footprint`: hipped, with every wing end turned into a gable.
    pub fn gabled(footprint: &Footprint) -> Result<Self, SkeletonError> {
        let mut skeleton = skeleton_of(footprint)?;
        let gables = raise_gables(&mut skeleton);
        Ok(Self::from_skeleton(skeleton, &gables))
    }

    fn from_skeleton(skeleton: Skeleton, gables: &[usize]) -> Self {
        let faces = (0..skeleton.faces.len())
            .filter(|e| !gables.contains(e))
            .map(|e| {
                let points = skeleton.face_points(e);
                let bounds = points.iter().fold(
                    [
                        f64::INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::NEG_INFINITY,
                    ],
                    |b, p| {
                        [
                            b[0].min(p[0]),
                            b[1].min(p[1]),
                            b[2].max(p[0]),
                            b[3].max(p[1]),
                        ]
                    },
                );
                RoofFace {
                    points,
                    edge: skeleton.edges[e],
                    bounds,
                }
            })
            .collect();
        // Where the roof bends: arcs between two faces that are not one plane, gables' hips
        // (now lying along their end walls) left out.
        let segments = skeleton
            .arcs
            .iter()
            .filter(|a| !a.faces.iter().any(|f| gables.contains(f)))
            .filter(|a| {
                let (e, f) = (&skeleton.edges[a.faces[0]], &skeleton.edges[a.faces[1]]);
                let same_plane =
                    e.n[0] * f.n[0] + e.n[1] * f.n[1] > 1.0 - 1e-12 && e.distance(f.a).abs() < 1e-9;
                !same_plane
            })
            .map(|a| [skeleton.nodes[a.nodes[0]].at, skeleton.nodes[a.nodes[1]].at])
            .collect();
        Self {
            faces,
            run: skeleton.max_time(),
            segments,
        }
    }

    /// The horizontal run from eaves to top (m): the latest time of the wavefront, half the
    /// width of the widest wing.
    pub fn run(&self) -> f64 {
        self.run
    }

    /// How far the roof has risen at `p`, in units of run: the distance from the edge whose face
    /// holds `p` (the nearest face for a point just outside them all).
    pub fn rise(&self, p: [f64; 2]) -> f64 {
        let mut nearest = (f64::INFINITY, 0.0);
        for face in &self.faces {
            let [x0, y0, x1, y1] = face.bounds;
            let outside_by = (x0 - p[0]).max(p[0] - x1).max(y0 - p[1]).max(p[1] - y1);
            if outside_by > nearest.0 {
                continue;
            }
            if outside_by <= 0.0 && inside(&face.points, p) {
                return face.edge.distance(p);
            }
            let n = face.points.len();
            let d = (0..n)
                .map(|i| segment_distance(p, face.points[i], face.points[(i + 1) % n]))
                .fold(f64::INFINITY, f64::min);
            if d < nearest.0 {
                nearest = (d, face.edge.distance(p));
            }
        }
        nearest.1
    }

    /// The descending level function: 0 at the top, 1 at the eaves.
    pub fn dlf(&self, p: [f64; 2]) -> f64 {
        if self.run <= 0.0 {
            return 0.0;
        }
        (1.0 - self.rise(p) / self.run).clamp(0.0, 1.0)
    }

    /// Where the roof bends, in metres.
    pub fn dividing_segments(&self) -> Vec<[[f64; 2]; 2]> {
        self.segments.clone()
    }
}

/// The skeleton of a footprint's outline and courtyards.
fn skeleton_of(footprint: &Footprint) -> Result<Skeleton, SkeletonError> {
    let rings: Vec<&[[f64; 2]]> = footprint.rings().map(|r| r.points.as_slice()).collect();
    Skeleton::of(&rings)
}

/// Turns each wing end into a gable: a triangular face whose apex only it and the faces of its
/// two (near-)parallel neighbours share has the apex moved along their common ridge until it
/// stands over the end wall. Both neighbouring faces stay planar (the apex moves along the line
/// where their planes meet). Answers the edges whose faces became gables.
fn raise_gables(s: &mut Skeleton) -> Vec<usize> {
    let parallel = GABLE_SIDES_WITHIN_DEGREES.to_radians().cos();
    let mut gables = Vec::new();
    for e in 0..s.faces.len() {
        if s.faces[e].len() != 3 {
            continue;
        }
        let apex = s.faces[e][2];
        let holders: Vec<usize> = (0..s.faces.len())
            .filter(|&f| f != e && s.faces[f].contains(&apex))
            .collect();
        let [f1, f2] = holders[..] else {
            continue;
        };
        let (n1, n2) = (s.edges[f1].n, s.edges[f2].n);
        if n1[0] * n2[0] + n1[1] * n2[1] > -parallel {
            continue;
        }
        // The ridge's direction in plan: where both planes rise alike.
        let d = [n1[0] - n2[0], n1[1] - n2[1]];
        let len = planar_length(d[0], d[1]);
        let r = [-d[1] / len, d[0] / len];
        let edge = s.edges[e];
        let toward = r[0] * edge.n[0] + r[1] * edge.n[1];
        if toward.abs() < 1e-6 {
            continue;
        }
        let node = s.nodes[apex];
        let step = -edge.distance(node.at) / toward;
        let at = [node.at[0] + step * r[0], node.at[1] + step * r[1]];
        // It must land on the end wall itself.
        let along = (at[0] - edge.a[0]) * edge.u[0] + (at[1] - edge.a[1]) * edge.u[1];
        let wall = planar_length(edge.b[0] - edge.a[0], edge.b[1] - edge.a[1]);
        if !(0.0..=wall).contains(&along) {
            continue;
        }
        let time = node.time + step * (r[0] * n1[0] + r[1] * n1[1]);
        if time <= 0.0 {
            continue;
        }
        s.nodes[apex].at = at;
        s.nodes[apex].time = time;
        gables.push(e);
    }
    gables
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::building::footprint::FootprintRing;

    fn footprint(outer: &[[f64; 2]], holes: &[&[[f64; 2]]]) -> Footprint {
        Footprint::new(
            FootprintRing::from_points(outer.to_vec()),
            holes
                .iter()
                .map(|h| FootprintRing::from_points(h.to_vec()))
                .collect(),
        )
        .unwrap()
    }

    const L: [[f64; 2]; 6] = [
        [0.0, 0.0],
        [20.0, 0.0],
        [20.0, 6.0],
        [6.0, 6.0],
        [6.0, 14.0],
        [0.0, 14.0],
    ];

    #[test]
    fn a_hipped_l_rises_from_every_wall() {
        let roof = SkeletonRoof::hipped(&footprint(&L, &[])).unwrap();
        assert_eq!(roof.run(), 3.0);
        // On the ridge of each wing, 3 m from both its sides.
        assert!((roof.rise([10.0, 3.0]) - 3.0).abs() < 1e-9);
        assert!((roof.rise([3.0, 9.0]) - 3.0).abs() < 1e-9);
        // The hip at the east end: 1 m in from the end wall, in the middle.
        assert!((roof.rise([19.0, 3.0]) - 1.0).abs() < 1e-9);
        // Next to the inner corner, 0.5 m from both inner walls, in the valley.
        assert!((roof.rise([5.5, 5.5]) - 0.5).abs() < 1e-9);
        assert_eq!(roof.dlf([0.0, 0.0]), 1.0);
        assert_eq!(roof.dlf([10.0, 3.0]), 0.0);
    }

    #[test]
    fn a_gabled_l_has_gables_at_both_wing_ends() {
        let roof = SkeletonRoof::gabled(&footprint(&L, &[])).unwrap();
        // The ridge runs right to the end walls.
        assert!((roof.rise([20.0, 3.0]) - 3.0).abs() < 1e-9);
        assert!((roof.rise([3.0, 14.0]) - 3.0).abs() < 1e-9);
        // Up the gable's edge from its corner.
        assert!((roof.rise([20.0, 1.0]) - 1.0).abs() < 1e-9);
        // The ridge meets each end wall at its middle: a dividing segment ends there.
        let ends: Vec<[f64; 2]> = roof.dividing_segments().into_iter().flatten().collect();
        assert!(ends.contains(&[20.0, 3.0]), "{ends:?}");
        assert!(ends.contains(&[3.0, 14.0]), "{ends:?}");
        // The gable ends' hips are gone: two ridges, the valley from the inner corner and the
        // hip from the outer one remain.
        assert_eq!(
            roof.dividing_segments().len(),
            4,
            "{:?}",
            roof.dividing_segments()
        );
    }

    #[test]
    fn a_courtyard_has_its_own_eaves() {
        let outer = [[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [0.0, 30.0]];
        let court = [[10.0, 10.0], [10.0, 20.0], [20.0, 20.0], [20.0, 10.0]];
        let roof = SkeletonRoof::hipped(&footprint(&outer, &[&court])).unwrap();
        assert_eq!(roof.run(), 5.0);
        assert!((roof.rise([10.0, 15.0])).abs() < 1e-9);
        assert!((roof.rise([7.0, 15.0]) - 3.0).abs() < 1e-9);
        assert!((roof.rise([5.0, 15.0]) - 5.0).abs() < 1e-9);
    }
}

//! Checking that a mesh is a closed, outward-facing surface: every edge is shared by exactly two
//! triangles that run it in opposite directions, no triangle is degenerate or has a NaN, and the
//! enclosed volume is positive (counter-clockwise triangles seen from outside).
//!
//! Vertices are welded by position first (to [`WELD`] metres), since each face carries its own
//! vertices.

use super::Mesh;
use foldhash::HashMap;

/// Positions closer than this (metres, per axis) are one vertex.
pub const WELD: f64 = 1e-6;

/// Positions welded to vertex ids in the order they are first seen, as both checks take them.
pub(super) struct Weld {
    ids: HashMap<[i64; 3], u32>,
    /// Each vertex id's position.
    pub points: Vec<[f64; 3]>,
}

impl Weld {
    pub(super) fn with_capacity(triangles: usize) -> Self {
        let mut ids = HashMap::default();
        ids.reserve(triangles);
        Self {
            ids,
            points: Vec::with_capacity(triangles),
        }
    }

    /// A triangle's welded corners, its corners less `origin` and its normal (twice its area
    /// long); `None` when it is degenerate: a non-finite coordinate, two corners welded
    /// together, or no area measured from `origin`.
    pub(super) fn triangle(&mut self, corners: [[f64; 3]; 3], origin: [f64; 3]) -> Option<Welded> {
        if corners.iter().flatten().any(|c| !c.is_finite()) {
            return None;
        }
        let id = corners.map(|p| {
            let key = p.map(|c| (c / WELD).round() as i64);
            let next = self.points.len() as u32;
            *self.ids.entry(key).or_insert_with(|| {
                self.points.push(p);
                next
            })
        });
        let [a, b, c] = corners.map(|p| [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]]);
        let n = super::triangle_normal(a, b, c);
        let area2 = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if id[0] == id[1] || id[1] == id[2] || id[0] == id[2] || area2 <= 1e-10 {
            return None;
        }
        Some(Welded {
            ids: id,
            corners: [a, b, c],
            normal: n,
        })
    }
}

/// A triangle [`Weld::triangle`] keeps.
pub(super) struct Welded {
    /// Its corners' vertex ids.
    pub ids: [u32; 3],
    /// Its corners less the origin.
    pub corners: [[f64; 3]; 3],
    /// Its normal, twice its area long.
    pub normal: [f64; 3],
}

/// The findings of [`check_closed`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ClosedReport {
    pub triangles: usize,
    /// Directed edges without a partner running the other way.
    pub open_edges: usize,
    /// Undirected edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Triangles with two welded corners equal, no area, or a non-finite coordinate.
    pub degenerate: usize,
    /// The enclosed volume in m³ (positive when faces point outwards).
    pub volume: f64,
}

impl ClosedReport {
    /// Closed, manifold, outward-facing and free of degenerate triangles.
    pub fn is_closed_and_outward(&self) -> bool {
        self.triangles > 0
            && self.open_edges == 0
            && self.non_manifold_edges == 0
            && self.degenerate == 0
            && self.volume > 0.0
    }
}

/// Checks the triangles of `mesh` with index in `range` as one surface.
pub fn check_closed(mesh: &Mesh, range: std::ops::Range<usize>) -> ClosedReport {
    let mut report = ClosedReport::default();
    let mut weld = Weld::with_capacity(range.len());
    let mut directed: HashMap<(u32, u32), i32> = HashMap::default();
    let origin = range
        .clone()
        .next()
        .map_or([0.0; 3], |t| mesh.positions[mesh.triangles[t][0] as usize]);
    for t in range {
        report.triangles += 1;
        let Some(Welded {
            ids: id,
            corners: [a, _, _],
            normal: n,
        }) = weld.triangle(mesh.corners(mesh.triangles[t]), origin)
        else {
            report.degenerate += 1;
            continue;
        };
        report.volume += (a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / 6.0;
        for k in 0..3 {
            *directed.entry((id[k], id[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut undirected: HashMap<(u32, u32), i32> = HashMap::default();
    for (&(a, b), &count) in &directed {
        let back = directed.get(&(b, a)).copied().unwrap_or(0);
        if count > back {
            report.open_edges += (count - back) as usize;
        }
        if a < b {
            *undirected.entry((a, b)).or_default() += count + back;
        }
    }
    report.non_manifold_edges = undirected.values().filter(|&&c| c > 2).count();
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceStyle, Material, Rgb};

    fn tetra(flip: bool) -> Mesh {
        let mut m = Mesh::default();
        for p in [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ] {
            m.push_vertex(p);
        }
        let style = FaceStyle::plain(Material::Wall, Rgb(0, 0, 0));
        for mut t in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
            if flip {
                t.swap(1, 2);
            }
            m.push_triangle(t, style);
        }
        m
    }

    #[test]
    fn a_tetrahedron_is_closed_and_its_mirror_faces_inwards() {
        let r = check_closed(&tetra(false), 0..4);
        assert!(r.is_closed_and_outward(), "{r:?}");
        assert!((r.volume - 1.0 / 6.0).abs() < 1e-12);
        let r = check_closed(&tetra(true), 0..4);
        assert!(r.volume < 0.0 && !r.is_closed_and_outward());
        let r = check_closed(&tetra(false), 0..3);
        assert_eq!(r.open_edges, 3);
    }
}

//! Splitting a closed surface into strict 2-manifold solids.
//!
//! Where two volumes of a group touch only along a line (two buildings meeting diagonally at a
//! corner), four or more triangles share that line's edges. The line is split between the
//! volumes: the triangles around such an edge are sorted by the angle they leave it at, and each
//! triangle is paired with its neighbour on the side its face points away from, so each pair
//! bounds one wedge of the inside. Triangles joined through paired edges form a solid. The surface
//! is a strict 2-manifold when every edge pairs this way, every pair runs the edge in opposite
//! directions, and no solid meets itself at a vertex (a pinch).
//!
//! The GLB gives each face its own vertices, so nothing in the file joins two solids; a tool that
//! welds vertices by position (val3dity with its snapping tolerance) joins them again and sees the
//! group as solids that touch, a `MultiSolid`.
//!
//! Vertices are welded by position first, as in [`super::check`].

use super::{Mesh, check::Weld};
use crate::union_find::UnionFind;
use foldhash::HashSet;

/// The findings of [`check_manifold`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ManifoldReport {
    /// Triangles with area (others are left out, as [`super::check_closed`] counts them).
    pub triangles: usize,
    /// Directed edges without a partner running the other way (as [`super::check_closed`]).
    pub open_edges: usize,
    /// Connected solids after edges shared by four or more triangles are split.
    pub solids: usize,
    /// Edges shared by four or more triangles that split cleanly between wedges of the inside.
    pub split_edges: usize,
    /// Edges that do not pair: open, an odd count, two neighbours around the edge running it the
    /// same way (volumes through each other), or two triangles leaving it at the same angle
    /// (faces over each other).
    pub unpaired_edges: usize,
    /// Vertices where one solid meets itself in two or more fans: it touches itself there.
    pub pinched_vertices: usize,
    /// Degenerate triangles (two welded corners equal, no area, or non-finite).
    pub degenerate: usize,
}

impl ManifoldReport {
    /// Every solid a strict 2-manifold.
    pub fn is_strict(&self) -> bool {
        self.triangles > 0
            && self.unpaired_edges == 0
            && self.pinched_vertices == 0
            && self.degenerate == 0
    }
}

/// What [`check_manifold`] finds, with each triangle's verdict.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Solids {
    pub report: ManifoldReport,
    /// Per triangle of the range: whether the solid it belongs to is a strict 2-manifold (false
    /// for a degenerate triangle).
    pub strict: Vec<bool>,
}

/// Checks the triangles of `mesh` with index in `range` as solids that may touch along lines.
pub fn check_manifold(mesh: &Mesh, range: std::ops::Range<usize>) -> Solids {
    let mut report = ManifoldReport::default();
    let mut weld = Weld::with_capacity(range.len());
    // Welded corners of every triangle with area, and where it stands in the range.
    let mut tris: Vec<[u32; 3]> = Vec::with_capacity(range.len());
    let mut index: Vec<u32> = Vec::with_capacity(range.len());
    let first = range.start;
    let mut strict = vec![false; range.len()];
    for t in range {
        let Some(welded) = weld.triangle(mesh.corners(mesh.triangles[t]), [0.0; 3]) else {
            report.degenerate += 1;
            continue;
        };
        tris.push(welded.ids);
        index.push((t - first) as u32);
    }
    report.triangles = tris.len();
    let points = weld.points;

    // Every triangle's edges as (low << 32 | high, triangle << 1 | runs low to high), sorted so
    // each edge's triangles lie together.
    let mut edges: Vec<(u64, u32)> = Vec::with_capacity(tris.len() * 3);
    for (t, id) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (id[k], id[(k + 1) % 3]);
            let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
            edges.push((key, ((t as u32) << 1) | u32::from(a < b)));
        }
    }
    edges.sort_unstable();

    // Corners (triangle * 3 + k), joined where two paired triangles share a vertex; triangles
    // at an edge that does not pair are faults.
    let mut corners = UnionFind::new(tris.len() * 3);
    let mut faults: Vec<u32> = Vec::new();
    let corner = |t: u32, v: u32| -> usize {
        let k = tris[t as usize].iter().position(|&c| c == v).unwrap_or(0);
        t as usize * 3 + k
    };
    let mut around: Vec<(u32, bool)> = Vec::new();
    for run in edges.chunk_by(|x, y| x.0 == y.0) {
        let edge = ((run[0].0 >> 32) as u32, run[0].0 as u32);
        around.clear();
        around.extend(run.iter().map(|&(_, v)| (v >> 1, v & 1 == 1)));
        let forward = around.iter().filter(|a| a.1).count();
        report.open_edges += forward.abs_diff(around.len() - forward);
        let mut join = |(a, b): (u32, u32)| {
            corners.union(corner(a, edge.0), corner(b, edge.0));
            corners.union(corner(a, edge.1), corner(b, edge.1));
        };
        if around.len() == 2 && around[0].1 != around[1].1 {
            join((around[0].0, around[1].0));
            continue;
        }
        let pairs = (around.len() >= 4 && around.len().is_multiple_of(2))
            .then(|| pair_around(edge, &around, &tris, &points))
            .flatten();
        match pairs {
            Some(pairs) => {
                report.split_edges += 1;
                pairs.into_iter().for_each(join);
            }
            None => {
                report.unpaired_edges += 1;
                faults.extend(around.iter().map(|&(t, _)| t));
            }
        }
    }

    // Solids: triangles joined through their corners' fans.
    let mut solids = UnionFind::new(tris.len());
    for c in 0..tris.len() * 3 {
        let root = corners.find(c);
        solids.union(c / 3, root / 3);
    }
    let solid: Vec<u32> = (0..tris.len()).map(|t| solids.find(t) as u32).collect();
    report.solids = solid
        .iter()
        .enumerate()
        .filter(|&(t, &s)| s as usize == t)
        .count();

    // A pinch: one vertex with two fans of the same solid. Each vertex keeps the first solid and
    // fan seen at it; corners of other solids there (rare: solids that touch) are sorted apart.
    let mut faulty: HashSet<u32> = faults.iter().map(|&t| solid[t as usize]).collect();
    let mut first_fan: Vec<(u32, u32)> = vec![(u32::MAX, u32::MAX); points.len()];
    let mut pinched_first: Vec<bool> = vec![false; points.len()];
    let mut others: Vec<(u32, u32, u32)> = Vec::new();
    for c in 0..tris.len() * 3 {
        let (v, s, fan) = (tris[c / 3][c % 3], solid[c / 3], corners.find(c) as u32);
        let first = &mut first_fan[v as usize];
        if first.0 == u32::MAX {
            *first = (s, fan);
        } else if first.0 != s {
            others.push((v, s, fan));
        } else if first.1 != fan && !pinched_first[v as usize] {
            pinched_first[v as usize] = true;
            report.pinched_vertices += 1;
            faulty.insert(s);
        }
    }
    others.sort_unstable();
    others.dedup();
    for run in others.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        if run.len() > 1 {
            report.pinched_vertices += 1;
            faulty.insert(run[0].1);
        }
    }
    for (t, &i) in index.iter().enumerate() {
        strict[i as usize] = !faulty.contains(&solid[t]);
    }
    Solids { report, strict }
}

/// Pairs the triangles around an edge shared by four or more: sorted by the angle each leaves
/// the edge at, each triangle running the edge low to high faces towards larger angles, so the
/// inside lies between it and the triangle before it. `None` when the directions do not
/// alternate or two triangles leave at the same angle.
fn pair_around(
    (low, high): (u32, u32),
    around: &[(u32, bool)],
    tris: &[[u32; 3]],
    points: &[[f64; 3]],
) -> Option<Vec<(u32, u32)>> {
    let (a, b) = (points[low as usize], points[high as usize]);
    let d = unit([b[0] - a[0], b[1] - a[1], b[2] - a[2]])?;
    // Any direction across the edge, and the one a quarter turn on.
    let pick = if d[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = unit(cross(d, pick))?;
    let w = cross(d, u);
    let mut sorted: Vec<(f64, u32, bool)> = around
        .iter()
        .map(|&(t, forward)| {
            let third = tris[t as usize]
                .iter()
                .copied()
                .find(|&c| c != low && c != high)
                .unwrap_or(low);
            let p = points[third as usize];
            let v = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
            (dot(v, w).atan2(dot(v, u)), t, forward)
        })
        .collect();
    sorted.sort_by(|x, y| x.0.total_cmp(&y.0));
    let n = sorted.len();
    const SAME_ANGLE: f64 = 1e-9;
    for i in 0..n {
        let (x, y) = (sorted[i], sorted[(i + 1) % n]);
        let gap = (y.0 - x.0).rem_euclid(std::f64::consts::TAU);
        if x.2 == y.2 || gap < SAME_ANGLE {
            return None;
        }
    }
    // Each triangle running low to high faces towards larger angles: it pairs with the one
    // before it.
    Some(
        (0..n)
            .filter(|&i| sorted[i].2)
            .map(|i| (sorted[(i + n - 1) % n].1, sorted[i].1))
            .collect(),
    )
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let len = dot(v, v).sqrt();
    (len > 0.0 && len.is_finite()).then(|| v.map(|c| c / len))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceStyle, Material, Rgb, check_closed};

    /// An axis-aligned box from `lo` to `hi`, counter-clockwise seen from outside.
    fn cuboid(m: &mut Mesh, lo: [f64; 3], hi: [f64; 3]) {
        let corner = |i: usize| {
            [
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            ]
        };
        let base = m.positions.len() as u32;
        for i in 0..8 {
            m.push_vertex(corner(i));
        }
        let style = FaceStyle::plain(Material::Wall, Rgb(0, 0, 0));
        // Each face's corners counter-clockwise from outside.
        for [a, b, c, d] in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ] {
            m.push_triangle([base + a, base + b, base + c], style);
            m.push_triangle([base + a, base + c, base + d], style);
        }
    }

    #[test]
    fn a_box_is_one_strict_solid() {
        let mut m = Mesh::default();
        cuboid(&mut m, [0.0; 3], [1.0, 2.0, 3.0]);
        assert!(check_closed(&m, 0..12).is_closed_and_outward());
        let s = check_manifold(&m, 0..12);
        assert_eq!(
            s.report,
            ManifoldReport {
                triangles: 12,
                solids: 1,
                ..Default::default()
            }
        );
        assert!(s.report.is_strict() && s.strict.iter().all(|&ok| ok));
    }

    #[test]
    fn boxes_touching_along_a_corner_line_are_two_strict_solids() {
        let mut m = Mesh::default();
        cuboid(&mut m, [0.0, 0.0, 0.0], [10.0, 10.0, 6.0]);
        cuboid(&mut m, [10.0, 10.0, 0.0], [20.0, 20.0, 6.0]);
        // By position, the line x = y = 10 from 0 to 6 m has four triangles.
        let closed = check_closed(&m, 0..24);
        assert_eq!((closed.open_edges, closed.non_manifold_edges), (0, 1));
        let s = check_manifold(&m, 0..24);
        assert_eq!(
            s.report,
            ManifoldReport {
                triangles: 24,
                solids: 2,
                split_edges: 1,
                ..Default::default()
            }
        );
        assert!(s.report.is_strict());
    }

    #[test]
    fn boxes_face_to_face_do_not_pair() {
        // Two closed boxes sharing a whole face: along its edges two faces leave at one angle.
        let mut m = Mesh::default();
        cuboid(&mut m, [0.0, 0.0, 0.0], [10.0, 10.0, 6.0]);
        cuboid(&mut m, [10.0, 0.0, 0.0], [20.0, 10.0, 6.0]);
        let s = check_manifold(&m, 0..24);
        assert_eq!(s.report.unpaired_edges, 5, "{:?}", s.report);
        assert!(!s.report.is_strict() && s.strict.iter().all(|&ok| !ok));
    }

    #[test]
    fn a_box_inside_out_along_a_shared_line_does_not_pair() {
        // Two boxes touching along a line, the second facing inwards: around the line two
        // neighbours run it the same way.
        let mut m = Mesh::default();
        cuboid(&mut m, [0.0, 0.0, 0.0], [10.0, 10.0, 6.0]);
        cuboid(&mut m, [10.0, 10.0, 0.0], [20.0, 20.0, 6.0]);
        for t in &mut m.triangles[12..] {
            t.swap(1, 2);
        }
        let s = check_manifold(&m, 0..24);
        assert_eq!(s.report.unpaired_edges, 1, "{:?}", s.report);
        assert!(!s.report.is_strict());
    }

    /// The surface of unit cubes at `cells`: every face between a filled cell and an empty one.
    fn voxels(cells: &[[i32; 3]]) -> Mesh {
        let mut m = Mesh::default();
        let style = FaceStyle::plain(Material::Wall, Rgb(0, 0, 0));
        let filled = |c: [i32; 3]| cells.contains(&c);
        for &c in cells {
            for axis in 0..3 {
                for side in [0, 1] {
                    let mut n = c;
                    n[axis] += if side == 1 { 1 } else { -1 };
                    if filled(n) {
                        continue;
                    }
                    // The face's corners, counter-clockwise seen from outside.
                    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                    let mut quad = [[0.0; 3]; 4];
                    for (k, (du, dv)) in [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
                        let mut p = c.map(f64::from);
                        p[axis] += side as f64;
                        p[u] += du as f64;
                        p[v] += dv as f64;
                        quad[k] = p;
                    }
                    if side == 0 {
                        quad.reverse();
                    }
                    let base = m.positions.len() as u32;
                    for p in quad {
                        m.push_vertex(p);
                    }
                    m.push_triangle([base, base + 1, base + 2], style);
                    m.push_triangle([base, base + 2, base + 3], style);
                }
            }
        }
        m
    }

    #[test]
    fn cubes_meeting_along_a_line_split_or_pinch() {
        // Side by side: one solid, no edge split.
        let m = voxels(&[[0, 0, 0], [1, 0, 0]]);
        assert!(check_closed(&m, 0..m.triangles.len()).is_closed_and_outward());
        let s = check_manifold(&m, 0..m.triangles.len()).report;
        assert_eq!((s.solids, s.split_edges, s.is_strict()), (1, 0, true));
        // Diagonal: two solids along one split edge.
        let m = voxels(&[[0, 0, 0], [1, 1, 0]]);
        let s = check_manifold(&m, 0..m.triangles.len()).report;
        assert_eq!((s.solids, s.split_edges, s.is_strict()), (2, 1, true));
        // Diagonal below, joined above (terraced houses on a slope, floors a step apart): one
        // solid that touches itself along the line, pinched where the line ends below.
        let m = voxels(&[[0, 0, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1]]);
        let closed = check_closed(&m, 0..m.triangles.len());
        assert_eq!((closed.open_edges, closed.non_manifold_edges), (0, 1));
        assert!((closed.volume - 5.0).abs() < 1e-12);
        let s = check_manifold(&m, 0..m.triangles.len());
        assert_eq!(
            (
                s.report.solids,
                s.report.split_edges,
                s.report.pinched_vertices
            ),
            (1, 1, 1)
        );
        assert!(!s.report.is_strict() && s.strict.iter().all(|&ok| !ok));
    }
}

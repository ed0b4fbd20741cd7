//! Triangulating a footprint for its roof and floor: every boundary point is kept (collinear nodes,
//! the points where dividing segments meet the walls, the points a neighbour's roof bends at), so
//! roof, floor and walls share their edges exactly, and the dividing segments are edges of the
//! triangulation, so each triangle lies in one virtual face where the roof is a plane.
//!
//! Convex outlines without inner constraints get a fan; the rest a constrained Delaunay
//! triangulation (spade), keeping the triangles inside the footprint.
use super::length::planar_length;

use super::footprint::{Footprint, orient};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// A planar triangulation: counter-clockwise triangles over `points`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanarMesh {
    pub points: Vec<[f64; 2]>,
    pub triangles: Vec<[u32; 3]>,
    /// Constraints that could not be kept (they crossed another one); the roof is still closed.
    pub dropped_constraints: usize,
}

/// Triangulates the region inside `footprint` whose boundary is `rings` (indices into `points`,
/// each ring in order, counter-clockwise outer and clockwise holes), with extra `constraints`.
/// Points past the rings' points are interior points; the result may add a centre point.
///
/// `on_edge[i]` is true for ring points that were added on an edge (not nodes): they lie on a
/// straight line with their neighbours, and no triangle may span them (see [`open_chords`]).
pub fn triangulate(
    footprint: &Footprint,
    mut points: Vec<[f64; 2]>,
    rings: &[std::ops::Range<usize>],
    constraints: &[[usize; 2]],
    on_edge: &[bool],
) -> PlanarMesh {
    if rings.len() == 1
        && constraints.is_empty()
        && points.len() == rings[0].len()
        && let Some(triangles) = convex_fan(&mut points, on_edge)
    {
        {
            return PlanarMesh {
                points,
                triangles,
                dropped_constraints: 0,
            };
        }
    }
    let origin = points[0];
    // The points (near the origin, where spade's predicates are most exact) and the edges to
    // keep; made again in the rare case the bulk load cannot be used, rather than copied for it.
    let local = || -> Vec<Point2<f64>> {
        points
            .iter()
            .map(|p| Point2::new(flush(p[0] - origin[0]), flush(p[1] - origin[1])))
            .collect()
    };
    let edges = || {
        let mut edges: Vec<[usize; 2]> = Vec::with_capacity(points.len() + constraints.len());
        for r in rings {
            for i in r.clone() {
                let next = if i + 1 == r.end { r.start } else { i + 1 };
                edges.push([i, next]);
            }
        }
        edges.extend(constraints.iter().filter(|[a, b]| a != b));
        edges
    };
    let mut dropped = 0;
    let n = points.len();
    let cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(
        local(),
        edges(),
        |_| dropped += 1,
    );
    let cdt = match cdt {
        Ok(cdt) if cdt.num_vertices() == n => cdt,
        // Duplicate points shift spade's indices: insert one by one instead.
        _ => {
            let (local, edges) = (local(), edges());
            dropped = 0;
            let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
            let mut handles = Vec::with_capacity(n);
            for p in &local {
                match cdt.insert(*p) {
                    Ok(h) => handles.push(h),
                    Err(_) => return PlanarMesh::default(),
                }
            }
            for [a, b] in &edges {
                if handles[*a] != handles[*b]
                    && cdt.try_add_constraint(handles[*a], handles[*b]).is_empty()
                {
                    dropped += 1;
                }
            }
            // Indices follow insertion order except for duplicates, which map to the first copy.
            let mut remap = vec![u32::MAX; cdt.num_vertices()];
            for (i, h) in handles.iter().enumerate().rev() {
                remap[h.index()] = i as u32;
            }
            let mut m = collect(footprint, points, rings, &cdt, &remap, dropped);
            open_chords(&mut m.triangles, rings, on_edge);
            return m;
        }
    };
    let remap: Vec<u32> = (0..n as u32).collect();
    let mut m = collect(footprint, points, rings, &cdt, &remap, dropped);
    open_chords(&mut m.triangles, rings, on_edge);
    m
}

/// Keeps the triangles inside the footprint: starting from the outside, crossing a ring edge
/// toggles between outside and inside (dividing segments do not). This is exact where a
/// point-in-polygon test is not: a sliver between three almost collinear ring points outside the
/// footprint has its centroid on the boundary.
fn collect(
    footprint: &Footprint,
    points: Vec<[f64; 2]>,
    rings: &[std::ops::Range<usize>],
    cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>,
    remap: &[u32],
    dropped: usize,
) -> PlanarMesh {
    let next = |i: usize| {
        rings
            .iter()
            .find(|r| r.contains(&i))
            .map(|r| if i + 1 == r.end { r.start } else { i + 1 })
    };
    let is_ring_edge = |a: usize, b: usize| next(a) == Some(b) || next(b) == Some(a);
    let mut inside: Vec<Option<bool>> = vec![None; cdt.num_all_faces()];
    let mut queue = std::collections::VecDeque::new();
    for face in cdt.inner_faces() {
        for e in face.adjacent_edges() {
            if e.rev().face().is_outer() {
                let (a, b) = (remap[e.from().fix().index()], remap[e.to().fix().index()]);
                let toggles = e.is_constraint_edge() && is_ring_edge(a as usize, b as usize);
                let slot = &mut inside[face.fix().index()];
                if slot.is_none() {
                    *slot = Some(toggles);
                    queue.push_back(face.fix());
                }
            }
        }
    }
    while let Some(f) = queue.pop_front() {
        let here = inside[f.index()].unwrap_or(false);
        for e in cdt.face(f).adjacent_edges() {
            let Some(other) = e.rev().face().as_inner() else {
                continue;
            };
            if inside[other.fix().index()].is_some() {
                continue;
            }
            let (a, b) = (remap[e.from().fix().index()], remap[e.to().fix().index()]);
            let toggles = e.is_constraint_edge() && is_ring_edge(a as usize, b as usize);
            inside[other.fix().index()] = Some(here != toggles);
            queue.push_back(other.fix());
        }
    }
    let mut triangles = Vec::with_capacity(cdt.num_inner_faces());
    for face in cdt.inner_faces() {
        if inside[face.fix().index()] != Some(true) {
            continue;
        }
        let t = face.vertices().map(|v| remap[v.fix().index()]);
        let [a, b, c] = t.map(|i| points[i as usize]);
        if orient(a, b, c) > 0.0 {
            triangles.push(t);
        }
    }
    // A ring edge spade had to split would break the parity: then fall back to centroids.
    let area: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| points[i as usize]);
            orient(a, b, c) / 2.0
        })
        .sum();
    let expected = footprint.area();
    if (area - expected).abs() > 1e-6 * expected.max(1.0) {
        triangles.clear();
        for face in cdt.inner_faces() {
            let t = face.vertices().map(|v| remap[v.fix().index()]);
            let [a, b, c] = t.map(|i| points[i as usize]);
            let centroid = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0];
            if orient(a, b, c) > 0.0 && footprint.contains(centroid) {
                triangles.push(t);
            }
        }
    }
    split_across_slivers(&points, &mut triangles);
    PlanarMesh {
        points,
        triangles,
        dropped_constraints: dropped,
    }
}

/// A triangle this thin (m, its height over its longest edge) has no area.
const SLIVER_HEIGHT: f64 = 1e-6;

/// Removes slivers: three interior points that are collinear up to rounding (where straight
/// skeleton nodes fall on another face's edge, as at a small bay) can give a triangle of no area
/// whose long edge is shared with a real triangle. The sliver goes, and the real triangle is
/// split at the sliver's middle point, so every edge still has its partner.
fn split_across_slivers(points: &[[f64; 2]], triangles: &mut [[u32; 3]]) {
    let p = |i: u32| points[i as usize];
    // For a sliver: its long edge (a, b) in its own direction, and the point m between them.
    let sliver = |t: &[u32; 3]| -> Option<(u32, u32, u32)> {
        (0..3).find_map(|k| {
            let (a, b, m) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            let (pa, pb, pm) = (p(a), p(b), p(m));
            let ab = [pb[0] - pa[0], pb[1] - pa[1]];
            let len2 = ab[0] * ab[0] + ab[1] * ab[1];
            if len2 == 0.0 {
                return None;
            }
            let t = ((pm[0] - pa[0]) * ab[0] + (pm[1] - pa[1]) * ab[1]) / len2;
            let height = orient(pa, pb, pm).abs() / len2.sqrt();
            (t > 0.0 && t < 1.0 && height < SLIVER_HEIGHT).then_some((a, b, m))
        })
    };
    // Each split removes a sliver, so this ends.
    for _ in 0..triangles.len() {
        let Some((i, (a, b, m))) = triangles
            .iter()
            .enumerate()
            .find_map(|(i, t)| sliver(t).map(|s| (i, s)))
        else {
            return;
        };
        // The triangle on the other side runs the edge from b to a.
        let other = triangles
            .iter()
            .position(|t| (0..3).any(|k| t[k] == b && t[(k + 1) % 3] == a));
        let Some(j) = other else {
            return;
        };
        let t = triangles[j];
        let k = (0..3).find(|&k| t[k] == b).unwrap_or(0);
        let c = t[(k + 2) % 3];
        triangles[j] = [b, m, c];
        triangles[i] = [m, a, c];
    }
}

/// Points added on a footprint edge lie on the edge's line only up to rounding, so a triangulation
/// may join the edge's two ends by a chord and leave a sliver of no area between the chord and the
/// points on it. This removes such slivers and replaces each triangle on a chord by a fan from its
/// third corner to every point of the chain, so no triangle is degenerate and the ring edges stay
/// triangle edges.
fn open_chords(triangles: &mut Vec<[u32; 3]>, rings: &[std::ops::Range<usize>], on_edge: &[bool]) {
    if !on_edge.iter().any(|&b| b) {
        return;
    }
    let next = |i: usize| {
        rings
            .iter()
            .find(|r| r.contains(&i))
            .map(|r| if i + 1 == r.end { r.start } else { i + 1 })
    };
    let added = |i: usize| on_edge.get(i).copied().unwrap_or(false);
    // The chain from a to b along the ring through added points only, when there is one.
    let chain = |a: usize, b: usize| -> Option<Vec<usize>> {
        let mut out = vec![a];
        let mut p = next(a)?;
        while p != b {
            if !added(p) || out.len() > on_edge.len() {
                return None;
            }
            out.push(p);
            p = next(p)?;
        }
        (out.len() > 1).then(|| {
            out.push(b);
            out
        })
    };
    let mut work: Vec<[u32; 3]> = std::mem::take(triangles);
    let mut guard = 0usize;
    while let Some(t) = work.pop() {
        guard += 1;
        if guard > 1_000_000 {
            break;
        }
        let mut replaced = false;
        for k in 0..3 {
            let (a, b, w) = (
                t[k] as usize,
                t[(k + 1) % 3] as usize,
                t[(k + 2) % 3] as usize,
            );
            if let Some(c) = chain(a, b) {
                if !c.contains(&w) {
                    for pair in c.windows(2) {
                        work.push([pair[0] as u32, pair[1] as u32, w as u32]);
                    }
                }
                replaced = true;
                break;
            }
        }
        if !replaced {
            triangles.push(t);
        }
    }
}

/// spade refuses coordinates that are tiny but not zero.
#[inline]
fn flush(x: f64) -> f64 {
    if x.abs() < 1e-30 { 0.0 } else { x }
}

/// A fan over a convex ring, or `None` when the ring is not convex. With collinear points the fan
/// starts at an added centre point, so no triangle is degenerate.
fn convex_fan(points: &mut Vec<[f64; 2]>, on_edge: &[bool]) -> Option<Vec<[u32; 3]>> {
    let n = points.len();
    // Points added on an edge are straight by construction, whatever rounding says.
    let mut straight = on_edge.iter().any(|&b| b);
    for i in 0..n {
        if on_edge.get(i).copied().unwrap_or(false) {
            continue;
        }
        let (a, b, c) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
        let o = orient(a, b, c);
        let scale =
            planar_length(b[0] - a[0], b[1] - a[1]) * planar_length(c[0] - b[0], c[1] - b[1]);
        // Within 1e-7 rad of a straight angle, a fan from a neighbour would make a sliver.
        if o < -1e-7 * scale {
            return None;
        }
        straight |= o <= 1e-7 * scale;
    }
    if !straight {
        return Some((1..n as u32 - 1).map(|i| [0, i, i + 1]).collect());
    }
    let c = points.iter().fold([0.0, 0.0], |s, p| {
        [s[0] + p[0] / n as f64, s[1] + p[1] / n as f64]
    });
    points.push(c);
    let centre = n as u32;
    Some(
        (0..n as u32)
            .map(|i| [centre, i, (i + 1) % n as u32])
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::building::footprint::FootprintRing;

    fn area(m: &PlanarMesh) -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.points[i as usize]);
                orient(a, b, c) / 2.0
            })
            .sum()
    }

    #[test]
    fn keeps_collinear_points_and_courtyards() {
        let outer = vec![
            [0.0, 0.0],
            [5.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
        ];
        let hole = vec![[3.0, 3.0], [3.0, 7.0], [7.0, 7.0], [7.0, 3.0]];
        let f = Footprint::new(
            FootprintRing::from_points(outer.clone()),
            vec![FootprintRing::from_points(hole.clone())],
        )
        .unwrap();
        let mut points = outer.clone();
        points.extend(&hole);
        let m = triangulate(&f, points, &[0..5, 5..9], &[], &[]);
        assert!((area(&m) - 84.0).abs() < 1e-9);
        // The collinear point (5, 0) is a corner of some triangle.
        assert!(m.triangles.iter().any(|t| t.contains(&1)));
    }

    #[test]
    fn a_convex_ring_with_a_straight_point_fans_from_its_centre() {
        let ring = vec![[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]];
        let f = Footprint::new(FootprintRing::from_points(ring.clone()), vec![]).unwrap();
        let m = triangulate(&f, ring, std::slice::from_ref(&(0..5)), &[], &[]);
        assert_eq!(m.points.len(), 6);
        assert_eq!(m.triangles.len(), 5);
        assert!(m.triangles.iter().all(|t| {
            let [a, b, c] = t.map(|i| m.points[i as usize]);
            orient(a, b, c) > 0.0
        }));
        assert!((area(&m) - 40.0).abs() < 1e-9);
    }

    #[test]
    fn constraints_become_edges() {
        let ring = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]];
        let f = Footprint::new(FootprintRing::from_points(ring.clone()), vec![]).unwrap();
        let mut points = ring.clone();
        points.extend([[2.0, 2.0], [8.0, 2.0]]);
        let m = triangulate(
            &f,
            points,
            std::slice::from_ref(&(0..4)),
            &[[4, 5], [0, 4], [3, 4], [1, 5], [2, 5]],
            &[],
        );
        assert!((area(&m) - 40.0).abs() < 1e-9);
        let has_edge = |a: u32, b: u32| {
            m.triangles
                .iter()
                .any(|t| (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b))
        };
        assert!(has_edge(4, 5) || has_edge(5, 4));
        assert_eq!(m.dropped_constraints, 0);
    }
}

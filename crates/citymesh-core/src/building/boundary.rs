//! Where the roof bends inside and along a footprint: the dividing segments of the roof shape cut
//! to the footprint (docs/method.md section 5). Each crossing of a dividing segment with a
//! footprint edge becomes an extra point on that edge (the wall's top bends there), and the pieces
//! inside become constraints of the roof triangulation.
//!
//! A point on an edge is stored as its parameter `sigma` from the edge's *canonical* start, the
//! end with the smaller [`NodeKey`], and its coordinates are always computed from that end. Two
//! buildings sharing the edge therefore compute the very same points.
use super::length::planar_length;

use super::footprint::{Footprint, FootprintRing, MERGE_DISTANCE, NodeKey};

/// One end of a constraint of the roof triangulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum End {
    /// A node of the footprint: ring and index.
    Node { ring: usize, index: usize },
    /// A point on edge `edge` (from node `edge` to the next) at canonical parameter `sigma`.
    Edge {
        ring: usize,
        edge: usize,
        sigma: f64,
    },
    /// A point strictly inside the footprint.
    Interior([f64; 2]),
}

/// The dividing segments of a roof cut to one footprint.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Divisions {
    /// Extra points per ring and edge, as canonical parameters in (0, 1), sorted ascending.
    pub splits: Vec<Vec<Vec<f64>>>,
    /// The pieces of dividing segments inside the footprint.
    pub constraints: Vec<[End; 2]>,
}

/// The canonical start and end node of edge `edge` of a ring: the end with the smaller key first.
#[inline]
pub fn canonical(ring: &FootprintRing, edge: usize) -> (usize, usize) {
    let next = (edge + 1) % ring.len();
    if ring.keys[edge] <= ring.keys[next] {
        (edge, next)
    } else {
        (next, edge)
    }
}

/// The point at canonical parameter `sigma` on edge `edge`.
#[inline]
pub fn edge_point(ring: &FootprintRing, edge: usize, sigma: f64) -> [f64; 2] {
    let (s, e) = canonical(ring, edge);
    let (a, b) = (ring.points[s], ring.points[e]);
    [a[0] + sigma * (b[0] - a[0]), a[1] + sigma * (b[1] - a[1])]
}

/// The key of the edge between two nodes, the same from both sides.
#[inline]
pub fn edge_key(a: NodeKey, b: NodeKey) -> (NodeKey, NodeKey) {
    if a <= b { (a, b) } else { (b, a) }
}

#[inline]
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Inserts `sigma` into a sorted list unless a point within [`MERGE_DISTANCE`] is there already.
pub fn insert_split(list: &mut Vec<f64>, sigma: f64, edge_length: f64) {
    insert_split_within(list, sigma, edge_length, MERGE_DISTANCE);
}

/// Inserts `sigma` into a sorted list unless a point within `distance` metres is there already.
pub fn insert_split_within(list: &mut Vec<f64>, sigma: f64, edge_length: f64, distance: f64) {
    let tol = distance / edge_length.max(f64::MIN_POSITIVE);
    if sigma <= tol || sigma >= 1.0 - tol {
        return;
    }
    let i = list.partition_point(|&s| s < sigma);
    let near = |j: usize| list.get(j).is_some_and(|&s| (s - sigma).abs() <= tol);
    if near(i) || (i > 0 && near(i - 1)) {
        return;
    }
    list.insert(i, sigma);
}

/// The length of edge `edge` of a ring.
#[inline]
pub fn edge_length(ring: &FootprintRing, edge: usize) -> f64 {
    let (a, b) = (ring.points[edge], ring.points[(edge + 1) % ring.len()]);
    planar_length(b[0] - a[0], b[1] - a[1])
}

/// Cuts dividing segments (metres) to a footprint.
pub fn divide(footprint: &Footprint, segments: &[[[f64; 2]; 2]]) -> Divisions {
    let rings: Vec<&FootprintRing> = footprint.rings().collect();
    let mut out = Divisions {
        splits: rings.iter().map(|r| vec![Vec::new(); r.len()]).collect(),
        constraints: Vec::new(),
    };
    for &[d0, d1] in segments {
        let dd = [d1[0] - d0[0], d1[1] - d0[1]];
        let len_d = planar_length(dd[0], dd[1]);
        if len_d <= MERGE_DISTANCE {
            continue;
        }
        let mut stops: Vec<(f64, End)> = vec![(0.0, End::Interior(d0)), (1.0, End::Interior(d1))];
        for (r, ring) in rings.iter().enumerate() {
            for e in 0..ring.len() {
                let (s, t) = canonical(ring, e);
                let (c0, c1) = (ring.points[s], ring.points[t]);
                let de = [c1[0] - c0[0], c1[1] - c0[1]];
                let len_e = planar_length(de[0], de[1]);
                let denom = cross(dd, de);
                if denom.abs() <= 1e-12 * len_d * len_e {
                    continue;
                }
                let w = [c0[0] - d0[0], c0[1] - d0[1]];
                let td = cross(w, de) / denom;
                let sigma = cross(w, dd) / denom;
                let (tol_d, tol_e) = (1e-7 / len_d, 1e-7 / len_e);
                if !(-tol_d..=1.0 + tol_d).contains(&td) || !(-tol_e..=1.0 + tol_e).contains(&sigma)
                {
                    continue;
                }
                let end = if sigma * len_e <= MERGE_DISTANCE {
                    End::Node { ring: r, index: s }
                } else if (1.0 - sigma) * len_e <= MERGE_DISTANCE {
                    End::Node { ring: r, index: t }
                } else {
                    insert_split(&mut out.splits[r][e], sigma, len_e);
                    End::Edge {
                        ring: r,
                        edge: e,
                        sigma,
                    }
                };
                stops.push((td.clamp(0.0, 1.0), end));
            }
        }
        stops.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Stops closer than the merge distance are one; a boundary stop wins over an end point.
        let mut merged: Vec<(f64, End)> = Vec::with_capacity(stops.len());
        for (t, end) in stops {
            match merged.last_mut() {
                Some(last) if (t - last.0) * len_d <= MERGE_DISTANCE => {
                    if matches!(last.1, End::Interior(_)) {
                        *last = (t, end);
                    }
                }
                _ => merged.push((t, end)),
            }
        }
        for pair in merged.windows(2) {
            let tm = (pair[0].0 + pair[1].0) / 2.0;
            let mid = [d0[0] + tm * dd[0], d0[1] + tm * dd[1]];
            if footprint.contains(mid) && footprint.distance_to_boundary(mid) > 1e-6 {
                out.constraints.push([pair[0].1, pair[1].1]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ridge_across_an_l_shape_splits_the_walls_it_meets() {
        // An L: the line y = 2 runs through both arms' walls.
        let outer = FootprintRing::from_points(vec![
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 4.0],
            [4.0, 4.0],
            [4.0, 10.0],
            [0.0, 10.0],
        ]);
        let f = Footprint::new(outer, vec![]).unwrap();
        let d = divide(&f, &[[[-1.0, 2.0], [11.0, 2.0]]]);
        // Splits on the west wall (x = 0) and the east wall (x = 10), one constraint inside.
        let count: usize = d.splits[0].iter().map(Vec::len).sum();
        assert_eq!(count, 2);
        assert_eq!(d.constraints.len(), 1);
        let [a, b] = d.constraints[0];
        let p = |e: End| match e {
            End::Edge { edge, sigma, .. } => edge_point(&f.outer, edge, sigma),
            other => panic!("expected a point on an edge, got {other:?}"),
        };
        let (pa, pb) = (p(a), p(b));
        assert!((pa[1] - 2.0).abs() < 1e-12 && (pb[1] - 2.0).abs() < 1e-12);
        assert!(((pa[0] - pb[0]).abs() - 10.0).abs() < 1e-12);
    }

    #[test]
    fn a_segment_ending_at_a_corner_ends_at_the_node() {
        let f = Footprint::new(
            FootprintRing::from_points(vec![[0.0, 0.0], [10.0, 0.0], [10.0, 4.0], [0.0, 4.0]]),
            vec![],
        )
        .unwrap();
        let d = divide(&f, &[[[8.0, 2.0], [10.0, 4.0]]]);
        assert!(d.splits[0].iter().all(Vec::is_empty));
        assert_eq!(d.constraints.len(), 1);
        assert!(matches!(d.constraints[0][0], End::Interior(_)));
        assert!(matches!(d.constraints[0][1], End::Node { ring: 0, .. }));
    }
}

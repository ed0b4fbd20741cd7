//! Tests of the straight skeleton: exact skeletons of known outlines, property tests on
//! random ones.

use super::vector::dist;
use super::*;
use proptest::prelude::*;

fn skeleton(rings: &[Vec<[f64; 2]>]) -> Skeleton {
    let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
    Skeleton::of(&refs).unwrap()
}

fn times(s: &Skeleton) -> Vec<f64> {
    let mut t: Vec<f64> = s.nodes.iter().map(|n| n.time).collect();
    t.sort_by(f64::total_cmp);
    t
}

#[test]
fn a_rectangle_has_a_ridge_and_four_hips() {
    // 20 m by 8 m: the ridge runs from (4, 4) to (16, 4), reached at 4 m.
    let s = skeleton(&[vec![[0.0, 0.0], [20.0, 0.0], [20.0, 8.0], [0.0, 8.0]]]);
    assert_eq!(s.nodes.len(), 6);
    assert_eq!(times(&s)[4..], [4.0, 4.0]);
    let mut ridge: Vec<[f64; 2]> = s.nodes[4..].iter().map(|n| n.at).collect();
    ridge.sort_by(|a, b| a[0].total_cmp(&b[0]));
    assert!((ridge[0][0] - 4.0).abs() < 1e-9 && (ridge[0][1] - 4.0).abs() < 1e-9);
    assert!((ridge[1][0] - 16.0).abs() < 1e-9 && (ridge[1][1] - 4.0).abs() < 1e-9);
    // Two trapezoids along the long sides, two triangles at the ends.
    let sizes: Vec<usize> = s.faces.iter().map(Vec::len).collect();
    assert_eq!(sizes, [4, 3, 4, 3]);
    assert_eq!(s.arcs.len(), 5);
}

#[test]
fn a_square_meets_in_its_centre() {
    let s = skeleton(&[vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]]);
    assert_eq!(s.nodes.len(), 5);
    assert_eq!(s.nodes[4].at, [5.0, 5.0]);
    assert_eq!(s.nodes[4].time, 5.0);
    assert!(s.faces.iter().all(|f| f.len() == 3));
}

#[test]
fn an_l_has_a_ridge_along_each_wing_and_a_valley() {
    // Wings 6 m wide: 20 m along x, 14 m along y.
    let s = skeleton(&[vec![
        [0.0, 0.0],
        [20.0, 0.0],
        [20.0, 6.0],
        [6.0, 6.0],
        [6.0, 14.0],
        [0.0, 14.0],
    ]]);
    assert!((s.max_time() - 3.0).abs() < 1e-9);
    // The ridge of the long wing ends 3 m from its end wall, at (17, 3); the other's at (3, 11).
    let at = |p: [f64; 2]| {
        s.nodes
            .iter()
            .any(|n| dist(n.at, p) < 1e-9 && n.time == 3.0)
    };
    assert!(at([17.0, 3.0]) && at([3.0, 11.0]) && at([3.0, 3.0]));
    // The valley runs from the inner corner (6, 6) to (3, 3).
    assert!(s.arcs.iter().any(|a| {
        let (p, q) = (s.nodes[a.nodes[0]].at, s.nodes[a.nodes[1]].at);
        (p == [6.0, 6.0] && dist(q, [3.0, 3.0]) < 1e-9)
            || (q == [6.0, 6.0] && dist(p, [3.0, 3.0]) < 1e-9)
    }));
}

#[test]
fn a_courtyard_gets_its_own_eaves() {
    // A 30 m square around a 10 m courtyard: a ring of roof 10 m wide, its ridge 5 m in.
    let s = skeleton(&[
        vec![[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [0.0, 30.0]],
        vec![[10.0, 10.0], [10.0, 20.0], [20.0, 20.0], [20.0, 10.0]],
    ]);
    assert_eq!(s.faces.len(), 8);
    assert!((s.max_time() - 5.0).abs() < 1e-9);
    for n in &s.nodes[8..] {
        assert!((n.time - 5.0).abs() < 1e-9, "{n:?}");
    }
}

#[test]
fn symmetric_outlines_where_events_coincide() {
    let shapes: [&[[f64; 2]]; 5] = [
        // A plus: four reflex corners reach the centre together.
        &[
            [4.0, 0.0],
            [8.0, 0.0],
            [8.0, 4.0],
            [12.0, 4.0],
            [12.0, 8.0],
            [8.0, 8.0],
            [8.0, 12.0],
            [4.0, 12.0],
            [4.0, 8.0],
            [0.0, 8.0],
            [0.0, 4.0],
            [4.0, 4.0],
        ],
        // An H.
        &[
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 6.0],
            [10.0, 6.0],
            [10.0, 0.0],
            [14.0, 0.0],
            [14.0, 16.0],
            [10.0, 16.0],
            [10.0, 10.0],
            [4.0, 10.0],
            [4.0, 16.0],
            [0.0, 16.0],
        ],
        // A T.
        &[
            [0.0, 10.0],
            [6.0, 10.0],
            [6.0, 0.0],
            [12.0, 0.0],
            [12.0, 10.0],
            [18.0, 10.0],
            [18.0, 16.0],
            [0.0, 16.0],
        ],
        // A U, wings as wide as the base.
        &[
            [0.0, 0.0],
            [20.0, 0.0],
            [20.0, 15.0],
            [14.0, 15.0],
            [14.0, 6.0],
            [6.0, 6.0],
            [6.0, 15.0],
            [0.0, 15.0],
        ],
        // A comb of three teeth.
        &[
            [0.0, 0.0],
            [22.0, 0.0],
            [22.0, 12.0],
            [18.0, 12.0],
            [18.0, 5.0],
            [13.0, 5.0],
            [13.0, 12.0],
            [9.0, 12.0],
            [9.0, 5.0],
            [4.0, 5.0],
            [4.0, 12.0],
            [0.0, 12.0],
        ],
    ];
    for ring in shapes {
        let s = Skeleton::of(&[ring]);
        assert!(s.is_ok(), "{:?} on {ring:?}", s.err());
    }
}

#[test]
fn regular_polygons_and_stars_where_every_event_is_at_once() {
    for n in [8usize, 24, 64] {
        let ring = |r_odd: f64| -> Vec<[f64; 2]> {
            (0..n)
                .map(|k| {
                    let a = k as f64 / n as f64 * std::f64::consts::TAU;
                    let r = if k % 2 == 0 { 30.0 } else { r_odd };
                    [r * a.cos(), r * a.sin()]
                })
                .collect()
        };
        // A regular polygon meets in its centre, at its inradius.
        let s = skeleton(&[ring(30.0)]);
        let inradius = 30.0 * (std::f64::consts::PI / n as f64).cos();
        assert!((s.max_time() - inradius).abs() < 1e-9, "{n}-gon");
        assert!(s.faces.iter().all(|f| f.len() == 3), "{n}-gon");
        // A star: its reflex corners all reach the centre together (shaken apart for
        // n >= 24); the outline's points stay exactly where they were.
        let star = ring(22.0);
        let s = skeleton(std::slice::from_ref(&star));
        for (k, p) in star.iter().enumerate() {
            assert_eq!(s.nodes[k].at, *p);
        }
        assert!(
            s.max_time() > 0.0 && s.max_time() < 22.0 + SHAKE,
            "{n}: {}",
            s.max_time()
        );
    }
}

#[test]
fn too_many_vertices_are_refused() {
    let ring: Vec<[f64; 2]> = (0..MAX_SKELETON_VERTICES + 1)
        .map(|k| {
            let a = k as f64 / (MAX_SKELETON_VERTICES + 1) as f64 * std::f64::consts::TAU;
            [100.0 * a.cos(), 100.0 * a.sin()]
        })
        .collect();
    assert_eq!(
        Skeleton::of(&[&ring]).unwrap_err(),
        SkeletonError::TooManyVertices
    );
}

/// A star-shaped ring around `c` with radii `r` at jittered angles, counter-clockwise.
fn star(c: [f64; 2], r: &[f64], jitter: &[f64]) -> Vec<[f64; 2]> {
    let n = r.len();
    (0..n)
        .map(|k| {
            let a = (k as f64 + 0.4 * jitter[k]) / n as f64 * std::f64::consts::TAU;
            [c[0] + r[k] * a.cos(), c[1] + r[k] * a.sin()]
        })
        .collect()
}

/// Rectilinear outlines, as many real buildings are: columns of the given widths, each
/// from `-below` to `above` (U, H, comb and staircase shapes), counter-clockwise.
fn blocks(widths: &[f64], below: &[f64], above: &[f64]) -> Vec<[f64; 2]> {
    let mut ring = Vec::new();
    let mut x = 0.0;
    for (w, b) in widths.iter().zip(below) {
        ring.push([x, -b]);
        ring.push([x + w, -b]);
        x += w;
    }
    for (w, a) in widths.iter().zip(above).rev() {
        ring.push([x, *a]);
        ring.push([x - w, *a]);
        x -= w;
    }
    // Drop repeated points (equal neighbours leave points in a row on one line: kept).
    ring.dedup_by(|a, b| dist(*a, *b) < 1e-9);
    if dist(ring[0], ring[ring.len() - 1]) < 1e-9 {
        ring.pop();
    }
    ring
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// On random star-shaped outlines, some with a courtyard: the skeleton exists and its
    /// check holds (faces tile the footprint, every node on each face's plane).
    #[test]
    fn random_outlines_have_consistent_skeletons(
        r in prop::collection::vec(8.0..30.0f64, 3..24),
        jitter in prop::collection::vec(-1.0..1.0f64, 24),
        hole in prop::option::of((0.5..3.0f64, 0.0..std::f64::consts::TAU)),
    ) {
        let outer = star([500.0, -300.0], &r, &jitter);
        let mut rings = vec![outer];
        if let Some((size, turn)) = hole {
            // A small square courtyard near the centre, clockwise.
            let (c, s) = (turn.cos() * size, turn.sin() * size);
            let courtyard = vec![
                [500.0 - c + s, -300.0 - s - c],
                [500.0 - c - s, -300.0 - s + c],
                [500.0 + c - s, -300.0 + s + c],
                [500.0 + c + s, -300.0 + s - c],
            ];
            // Only a courtyard well inside the outline.
            let o = &rings[0];
            prop_assume!(courtyard.iter().all(|&p| {
                crate::building::footprint::inside(o, p)
                    && (0..o.len()).all(|k| {
                        crate::building::footprint::segment_distance(p, o[k], o[(k + 1) % o.len()]) > 0.5
                    })
            }));
            rings.push(courtyard);
        }
        let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
        let s = Skeleton::of(&refs);
        prop_assert!(s.is_ok(), "{:?} on {:?}", s.err(), rings);
    }

    /// Rectilinear outlines with many equal coordinates (simultaneous events, parallel
    /// edges meeting): the skeleton exists and its check holds.
    #[test]
    fn rectilinear_outlines_have_consistent_skeletons(
        widths in prop::collection::vec(prop::sample::select(vec![4.0, 6.0, 8.0, 10.0, 12.5]), 1..7),
        below in prop::collection::vec(prop::sample::select(vec![0.0, 2.0, 4.0, 6.0]), 7),
        above in prop::collection::vec(prop::sample::select(vec![4.0, 6.0, 8.0, 10.0, 14.0]), 7),
        courtyard in prop::option::of((0usize..7, 0.5..1.5f64)),
    ) {
        let n = widths.len();
        let ring = blocks(&widths, &below[..n], &above[..n]);
        let mut rings = vec![ring];
        if let Some((column, size)) = courtyard {
            // A square courtyard in the middle of one column, clockwise, if it fits.
            let k = column % n;
            let x: f64 = widths[..k].iter().sum::<f64>() + widths[k] / 2.0;
            let y = (above[k] - below[k]) / 2.0;
            let h = size.min(widths[k] / 4.0).min((above[k] + below[k]) / 4.0);
            rings.push(vec![[x - h, y - h], [x - h, y + h], [x + h, y + h], [x + h, y - h]]);
        }
        let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
        let s = Skeleton::of(&refs);
        prop_assert!(s.is_ok(), "{:?} on {:?}", s.err(), rings);
    }
}

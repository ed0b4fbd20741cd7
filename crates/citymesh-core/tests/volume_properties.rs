//! Property tests: on random footprints (convex, concave, L/T/U shapes, courtyards, thin and
//! near-degenerate ones, collinear and repeated nodes, either winding) with any roof shape and
//! heights, the generator never panics, and whatever it builds is closed and outward-facing. Rows
//! of houses sharing walls stay closed as one surface with their hidden walls removed.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::building::RoofMethod;
use citymesh_core::building::footprint::{Footprint, FootprintRing};
use citymesh_core::building::roof::RoofShape;
use citymesh_core::building::skeleton_roof::SkeletonRoof;
use citymesh_core::geo::{GeoBbox, LocalFrame};
use citymesh_core::mesh::check_closed;
use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use citymesh_core::scene::{Border, Scene, SceneRules};
use citymesh_core::terrain::ElevationModel;
use proptest::prelude::*;

fn bbox() -> GeoBbox {
    GeoBbox::new(8.39, 48.99, 8.41, 49.01).unwrap()
}

fn frame() -> LocalFrame {
    let (lon, lat) = bbox().center();
    LocalFrame::new(lon, lat, 0.0)
}

fn ring(points: &[[f64; 2]], first_id: i64) -> Ring {
    let f = frame();
    Ring {
        nodes: points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let (lon, lat, _) = f.to_geographic([p[0], p[1], 0.0]);
                RingNode {
                    id: Some(first_id + i as i64),
                    lon,
                    lat,
                }
            })
            .collect(),
    }
}

#[derive(Debug, Clone)]
struct Roof {
    shape: RoofShape,
    across: bool,
    height: f64,
    roof_height: f64,
    min_height: f64,
}

fn roof() -> impl Strategy<Value = Roof> {
    (
        prop::sample::select(RoofShape::ALL.to_vec()),
        any::<bool>(),
        2.0..60.0f64,
        0.0..12.0f64,
        0.0..1.0f64,
    )
        .prop_map(|(shape, across, height, roof_height, min)| Roof {
            shape,
            across,
            height,
            roof_height,
            min_height: min * height * 0.8,
        })
}

fn tags(r: &Roof, direction: f64) -> Tags {
    let mut t: Tags = [
        ("building", "yes".to_owned()),
        ("height", format!("{}", r.height)),
        ("roof:height", format!("{}", r.roof_height)),
        ("roof:shape", r.shape.tag().to_owned()),
        ("roof:direction", format!("{direction}")),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_owned(), v))
    .collect();
    if r.across {
        t.insert("roof:orientation".into(), "across".into());
    }
    if r.min_height > 0.0 {
        t.insert("min_height".into(), format!("{}", r.min_height));
    }
    t
}

fn rotate(points: Vec<[f64; 2]>, angle: f64, at: [f64; 2]) -> Vec<[f64; 2]> {
    let (s, c) = angle.sin_cos();
    points
        .into_iter()
        .map(|[x, y]| [at[0] + x * c - y * s, at[1] + x * s + y * c])
        .collect()
}

/// Footprints of every kind the tests cover, as (outer, holes).
fn footprint() -> impl Strategy<Value = (Vec<[f64; 2]>, Vec<Vec<[f64; 2]>>)> {
    let convex = (
        3usize..12,
        3.0..40.0f64,
        0.2..1.0f64,
        prop::collection::vec(0.0..1.0f64, 12),
    )
        .prop_map(|(n, r, squash, jitter)| {
            let mut angles: Vec<f64> = (0..n)
                .map(|i| (i as f64 + 0.8 * jitter[i]) * std::f64::consts::TAU / n as f64)
                .collect();
            angles.sort_by(f64::total_cmp);
            let outer = angles
                .iter()
                .map(|a| [r * a.cos(), r * squash * a.sin()])
                .collect();
            (outer, vec![])
        });
    let star = (5usize..16, prop::collection::vec(2.0..30.0f64, 16)).prop_map(|(n, radii)| {
        let outer = (0..n)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / n as f64;
                [radii[i] * a.cos(), radii[i] * a.sin()]
            })
            .collect();
        (outer, vec![])
    });
    // L, T and U shapes from a grid of unit cells.
    let letters = (0usize..3, 4.0..20.0f64, 2.0..10.0f64).prop_map(|(kind, a, b)| {
        let outer = match kind {
            0 => vec![[0.0, 0.0], [a, 0.0], [a, b], [b, b], [b, a], [0.0, a]],
            1 => vec![
                [0.0, 0.0],
                [3.0 * b, 0.0],
                [3.0 * b, b],
                [2.0 * b, b],
                [2.0 * b, b + a],
                [b, b + a],
                [b, b],
                [0.0, b],
            ],
            _ => vec![
                [0.0, 0.0],
                [3.0 * b, 0.0],
                [3.0 * b, a + b],
                [2.0 * b, a + b],
                [2.0 * b, b],
                [b, b],
                [b, a + b],
                [0.0, a + b],
            ],
        };
        (outer, vec![])
    });
    let courtyard =
        (10.0..50.0f64, 10.0..40.0f64, 0.1..0.8f64, 0.1..0.8f64).prop_map(|(w, h, fx, fy)| {
            let outer = vec![[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]];
            let (hw, hh) = (w * fx, h * fy);
            let (x0, y0) = ((w - hw) / 2.0, (h - hh) / 2.0);
            let hole = vec![[x0, y0], [x0, y0 + hh], [x0 + hw, y0 + hh], [x0 + hw, y0]];
            (outer, vec![hole])
        });
    let thin = (1.0..30.0f64, 0.01..0.6f64)
        .prop_map(|(l, w)| (vec![[0.0, 0.0], [l, 0.0], [l, w], [0.0, w]], vec![]));
    let base = prop_oneof![convex, star, letters, courtyard, thin];
    (
        base,
        -3.2..3.2f64,
        prop::collection::vec(0usize..4, 0..4),
        any::<bool>(),
        -500.0..500.0f64,
    )
        .prop_map(|((outer, holes), angle, extras, reverse, shift)| {
            // Collinear midpoints and repeated nodes, then rotation, position and winding.
            let mut o = outer.clone();
            for (k, &e) in extras.iter().enumerate() {
                let i = (e + k) % o.len();
                let (p, q) = (o[i], o[(i + 1) % o.len()]);
                if k % 2 == 0 {
                    o.insert(i + 1, [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0]);
                } else {
                    o.insert(i + 1, p);
                }
            }
            let at = [shift, shift * 0.7];
            let mut o = rotate(o, angle, at);
            if reverse {
                o.reverse();
            }
            let holes = holes.into_iter().map(|h| rotate(h, angle, at)).collect();
            (o, holes)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn every_volume_is_closed_and_outward((outer, holes) in footprint(), r in roof(), direction in 0.0..360.0f64) {
        let inners: Vec<Ring> = holes.iter().enumerate().map(|(i, h)| ring(h, 1000 * (i as i64 + 1))).collect();
        let record = BuildingRecord {
            id: OsmId::Way(7),
            is_part: false,
            outers: vec![ring(&outer, 1)],
            inners,
            tags: tags(&r, direction),
        };
        let scene = Scene::new(&ElevationModel::default(), &bbox(), &[vec![&record]], Border::Whole);
        let range = scene.cluster_triangles[0].clone();
        if scene.buildings.generated == 1 {
            let report = check_closed(&scene.mesh, range);
            prop_assert!(report.is_closed_and_outward(), "{report:?}");
        } else {
            // Only footprints without area or crossing themselves are refused.
            prop_assert_eq!(scene.buildings.total_skipped(), 1);
            prop_assert!(range.is_empty());
        }
    }

    /// Hipped, gabled and pyramidal roofs laid over the straight skeleton of every kind of
    /// footprint: each volume is closed and outward, and the roof is built as asked (not
    /// flattened, nor the skeleton given up for the virtual rectangle).
    #[test]
    fn skeleton_roofs_are_closed_on_every_footprint(
        (outer, holes) in footprint(),
        shape in prop::sample::select(vec![RoofShape::Hipped, RoofShape::Gabled, RoofShape::Pyramidal]),
        (height, roof_height) in (4.0..40.0f64, 0.0..12.0f64),
    ) {
        let inners: Vec<Ring> = holes.iter().enumerate().map(|(i, h)| ring(h, 1000 * (i as i64 + 1))).collect();
        let r = Roof { shape, across: false, height, roof_height, min_height: 0.0 };
        let record = BuildingRecord {
            id: OsmId::Way(7),
            is_part: false,
            outers: vec![ring(&outer, 1)],
            inners,
            tags: tags(&r, 0.0),
        };
        // The skeleton exists for every footprint the generator accepts.
        let footprint = Footprint::new(
            FootprintRing::from_points(outer.clone()),
            holes.iter().map(|h| FootprintRing::from_points(h.clone())).collect(),
        );
        if let Ok(f) = &footprint {
            let built = SkeletonRoof::gabled(f).and(SkeletonRoof::hipped(f));
            prop_assert!(built.is_ok(), "{:?}", built.err());
        }
        let rules = SceneRules { roof_method: RoofMethod::Skeleton, ..SceneRules::new(Border::Whole) };
        let scene = Scene::new_with_rules(&ElevationModel::default(), &bbox(), &[vec![&record]], rules);
        let range = scene.cluster_triangles[0].clone();
        if scene.buildings.generated == 1 {
            let report = check_closed(&scene.mesh, range);
            prop_assert!(report.is_closed_and_outward(), "{report:?}");
            prop_assert!(scene.buildings.repaired_ids.is_empty(), "{:?}", scene.buildings.repaired_ids);
        } else {
            prop_assert_eq!(scene.buildings.total_skipped(), 1);
        }
    }

    #[test]
    fn a_row_of_houses_is_one_closed_surface(
        widths in prop::collection::vec(4.0..12.0f64, 2..6),
        depth in 6.0..15.0f64,
        roofs in prop::collection::vec(roof(), 6),
        angle in -3.2..3.2f64,
    ) {
        // Houses side by side: neighbours share the two nodes of their common wall.
        let mut x = 0.0;
        let mut records = Vec::new();
        for (i, w) in widths.iter().enumerate() {
            let pts = rotate(vec![[x, 0.0], [x + w, 0.0], [x + w, depth], [x, depth]], angle, [0.0, 0.0]);
            let mut r = ring(&pts, 0);
            let id = |k: i64| 10 * k;
            r.nodes[0].id = Some(id(i as i64));
            r.nodes[3].id = Some(id(i as i64) + 1);
            r.nodes[1].id = Some(id(i as i64 + 1));
            r.nodes[2].id = Some(id(i as i64 + 1) + 1);
            records.push(BuildingRecord {
                id: OsmId::Way(i as i64 + 1),
                is_part: false,
                outers: vec![r],
                inners: vec![],
                tags: tags(&roofs[i], 90.0),
            });
            x += w;
        }
        let refs: Vec<&BuildingRecord> = records.iter().collect();
        let scene = Scene::new(&ElevationModel::default(), &bbox(), &[refs], Border::Whole);
        prop_assert_eq!(scene.buildings.generated, widths.len());
        prop_assert!(scene.buildings.shared_walls < widths.len());
        let report = check_closed(&scene.mesh, scene.cluster_triangles[0].clone());
        prop_assert!(report.is_closed_and_outward(), "{report:?}");
    }
}

/// A hipped roof over an outline past the skeleton's limit (a 130-pointed star) keeps the
/// virtual rectangle, says so by id, and is still closed.
#[test]
fn a_roof_past_the_skeletons_limit_keeps_the_rectangle_and_says_so() {
    use citymesh_core::building::straight_skeleton::MAX_SKELETON_VERTICES;
    let n = MAX_SKELETON_VERTICES + 2;
    let star: Vec<[f64; 2]> = (0..n)
        .map(|k| {
            let a = k as f64 / n as f64 * std::f64::consts::TAU;
            let r = if k % 2 == 0 { 30.0 } else { 22.0 };
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    let r = Roof {
        shape: RoofShape::Hipped,
        across: false,
        height: 12.0,
        roof_height: 4.0,
        min_height: 0.0,
    };
    let record = BuildingRecord {
        id: OsmId::Way(7),
        is_part: false,
        outers: vec![ring(&star, 1)],
        inners: Vec::new(),
        tags: tags(&r, 0.0),
    };
    let scene = Scene::new(
        &ElevationModel::default(),
        &bbox(),
        &[vec![&record]],
        Border::Whole,
    );
    assert_eq!(scene.buildings.generated, 1);
    assert_eq!(
        scene.buildings.repaired_ids,
        vec![("way/7".to_owned(), "roof_on_virtual_rectangle")]
    );
    let report = check_closed(&scene.mesh, scene.cluster_triangles[0].clone());
    assert!(report.is_closed_and_outward(), "{report:?}");
}

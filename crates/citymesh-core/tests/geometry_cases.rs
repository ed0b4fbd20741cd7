//! Outlines real data draws that are easy to get wrong, each built from OSM-like records in a
//! local frame: courtyards that share an edge, a part touching its outline at one node, a small
//! bay. Each asserts the exact floor area drawn (the outline less its courtyards and parts, to
//! 0.01 m²), the repair reported by id, and a closed group whose every edge has two triangles.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::geo::{GeoBbox, LocalFrame};
use citymesh_core::mesh::{Material, check_closed, check_manifold};
use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;
use std::collections::BTreeMap;

const BBOX: [f64; 4] = [8.399, 48.999, 8.401, 49.001];

fn frame() -> LocalFrame {
    let bbox = GeoBbox::new(BBOX[0], BBOX[1], BBOX[2], BBOX[3]).unwrap();
    let (lon, lat) = bbox.center();
    LocalFrame::new(lon, lat, 0.0)
}

/// A ring of OSM nodes `(id, x, y)` (local metres), open.
fn ring(nodes: &[(i64, f64, f64)]) -> Ring {
    let frame = frame();
    Ring {
        nodes: nodes
            .iter()
            .map(|&(id, x, y)| {
                let (lon, lat, _) = frame.to_geographic([x, y, 0.0]);
                RingNode {
                    id: Some(id),
                    lon,
                    lat,
                }
            })
            .collect(),
    }
}

fn record(
    id: OsmId,
    is_part: bool,
    outer: Ring,
    inners: Vec<Ring>,
    tags: &[(&str, &str)],
) -> BuildingRecord {
    BuildingRecord {
        id,
        is_part,
        outers: vec![outer],
        inners,
        tags: tags
            .iter()
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect(),
    }
}

/// One cluster's scene on flat ground.
fn scene(records: &[&BuildingRecord]) -> Scene {
    let bbox = GeoBbox::new(BBOX[0], BBOX[1], BBOX[2], BBOX[3]).unwrap();
    let scene = Scene::new(
        &ElevationModel::default(),
        &bbox,
        &[records.to_vec()],
        Border::Whole,
    );
    assert_eq!(scene.frame, frame());
    scene
}

/// Floor area drawn per building id.
fn floors(scene: &Scene) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    let m = &scene.mesh;
    for (t, tri) in m.triangles.iter().enumerate() {
        if m.styles[t].material != Material::Floor {
            continue;
        }
        let [a, b, c] = m.corners(*tri);
        let area = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() / 2.0;
        let id = scene.buildings.features[m.styles[t].feature as usize]
            .id
            .to_string();
        *out.entry(id).or_default() += area;
    }
    out
}

/// The group is closed, outward, and every edge is shared by exactly two triangles.
fn assert_strict_solid(scene: &Scene, what: &str) {
    for range in &scene.cluster_triangles {
        let r = check_closed(&scene.mesh, range.clone());
        assert!(
            r.triangles > 0
                && r.open_edges == 0
                && r.non_manifold_edges == 0
                && r.degenerate == 0
                && r.volume > 0.0,
            "{what}: {r:?}"
        );
    }
}

fn repairs(scene: &Scene) -> Vec<(String, &'static str)> {
    scene.buildings.repaired_ids.clone()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 0.01
}

#[test]
fn two_courtyards_sharing_an_edge_are_both_left_open() {
    // A 100 m x 60 m block with two 20 m x 10 m courtyards side by side: they share the edge
    // from node 12 to node 13.
    let outer = ring(&[
        (1, 0.0, 0.0),
        (2, 100.0, 0.0),
        (3, 100.0, 60.0),
        (4, 0.0, 60.0),
    ]);
    let a = ring(&[
        (10, 10.0, 20.0),
        (11, 10.0, 30.0),
        (13, 30.0, 30.0),
        (12, 30.0, 20.0),
    ]);
    let b = ring(&[
        (12, 30.0, 20.0),
        (13, 30.0, 30.0),
        (15, 50.0, 30.0),
        (14, 50.0, 20.0),
    ]);
    let block = record(
        OsmId::Relation(1),
        false,
        outer,
        vec![a, b],
        &[("building", "apartments"), ("height", "12")],
    );
    let s = scene(&[&block]);
    let drawn = floors(&s)["relation/1"];
    assert!(close(drawn, 6000.0 - 400.0), "{drawn}");
    // The quality record says so too.
    let q = &s.buildings.features[0].quality;
    assert!(q.closed && q.strict_manifold, "{q:?}");
    assert_eq!(q.repairs, vec!["courtyard_touches_a_ring"]);
    assert!(
        close(q.floor_area, 5600.0) && close(q.outline_area, 5600.0),
        "{q:?}"
    );
    assert_eq!(
        repairs(&s),
        vec![("relation/1".to_owned(), "courtyard_touches_a_ring")]
    );
    assert_eq!(s.buildings.area_lost_ids, vec![]);
    assert_strict_solid(&s, "");
}

#[test]
fn a_courtyard_touching_the_outline_at_a_node_is_left_open() {
    // A 40 m x 20 m block whose 8 m x 8 m diamond courtyard touches the outline at node 2.
    let outer = ring(&[
        (1, 0.0, 0.0),
        (2, 20.0, 0.0),
        (3, 40.0, 0.0),
        (4, 40.0, 20.0),
        (5, 0.0, 20.0),
    ]);
    let yard = ring(&[
        (2, 20.0, 0.0),
        (6, 24.0, 4.0),
        (7, 20.0, 8.0),
        (8, 16.0, 4.0),
    ]);
    let block = record(
        OsmId::Relation(2),
        false,
        outer,
        vec![yard],
        &[("building", "yes"), ("height", "9")],
    );
    let s = scene(&[&block]);
    let drawn = floors(&s)["relation/2"];
    assert!(close(drawn, 800.0 - 32.0), "{drawn}");
    let r = repairs(&s);
    assert!(
        r.contains(&("relation/2".to_owned(), "courtyard_touches_a_ring")),
        "{r:?}"
    );
    assert!(
        r.contains(&("relation/2".to_owned(), "split_where_rings_touch")),
        "{r:?}"
    );
    assert_eq!(s.buildings.area_lost_ids, vec![]);
    let c = check_closed(&s.mesh, s.cluster_triangles[0].clone());
    assert!(
        c.open_edges == 0 && c.degenerate == 0 && c.volume > 0.0,
        "{c:?}"
    );
    // The footprint touches itself at node 2, so the block touches itself along that corner
    // line: one solid, pinched at the line's ends, and the record says it is not strict.
    let solids = check_manifold(&s.mesh, s.cluster_triangles[0].clone()).report;
    assert_eq!(
        (solids.solids, solids.split_edges, solids.pinched_vertices),
        (1, 1, 2),
        "{solids:?}"
    );
    let q = &s.buildings.features[0].quality;
    assert!(q.closed && !q.strict_manifold, "{q:?}");
}

#[test]
fn a_part_touching_its_outline_at_one_node_is_cut_out_of_it() {
    // A 20 m x 10 m, 3 m outline; inside it a 6 m part, a diamond of 32 m² whose lowest node
    // (node 2) is a node of the outline's south wall.
    let outline = record(
        OsmId::Way(1),
        false,
        ring(&[
            (1, 0.0, 0.0),
            (2, 10.0, 0.0),
            (3, 20.0, 0.0),
            (4, 20.0, 10.0),
            (5, 0.0, 10.0),
        ]),
        vec![],
        &[("building", "yes"), ("height", "3")],
    );
    let part = record(
        OsmId::Way(2),
        true,
        ring(&[
            (2, 10.0, 0.0),
            (6, 14.0, 4.0),
            (7, 10.0, 8.0),
            (8, 6.0, 4.0),
        ]),
        vec![],
        &[("building:part", "yes"), ("height", "6")],
    );
    let s = scene(&[&outline, &part]);
    let f = floors(&s);
    assert!(close(f["way/1"], 200.0 - 32.0), "{f:?}");
    assert!(close(f["way/2"], 32.0), "{f:?}");
    assert_eq!(
        repairs(&s),
        vec![("way/1".to_owned(), "split_where_rings_touch")]
    );
    assert_eq!(s.buildings.area_lost_ids, vec![]);
    let c = check_closed(&s.mesh, s.cluster_triangles[0].clone());
    assert!(
        c.open_edges == 0 && c.degenerate == 0 && c.volume > 0.0,
        "{c:?}"
    );
    let solids = check_manifold(&s.mesh, s.cluster_triangles[0].clone()).report;
    assert!(solids.is_strict(), "{c:?} {solids:?}");
}

#[test]
fn a_part_sharing_an_edge_with_its_outline_is_cut_out_of_it() {
    let outline = record(
        OsmId::Way(1),
        false,
        ring(&[
            (1, 0.0, 0.0),
            (2, 6.0, 0.0),
            (3, 20.0, 0.0),
            (4, 20.0, 10.0),
            (5, 0.0, 10.0),
            (6, 0.0, 4.0),
        ]),
        vec![],
        &[("building", "yes"), ("height", "3")],
    );
    let part = record(
        OsmId::Way(2),
        true,
        ring(&[(1, 0.0, 0.0), (2, 6.0, 0.0), (7, 6.0, 4.0), (6, 0.0, 4.0)]),
        vec![],
        &[("building:part", "yes"), ("height", "6")],
    );
    let s = scene(&[&outline, &part]);
    let f = floors(&s);
    assert!(close(f["way/1"], 200.0 - 24.0), "{f:?}");
    assert!(close(f["way/2"], 24.0), "{f:?}");
    assert_eq!(repairs(&s), vec![]);
    assert_eq!(s.buildings.area_lost_ids, vec![]);
    assert_strict_solid(&s, "");
}

#[test]
fn a_small_bay_is_drawn_with_every_roof() {
    // A 20 m x 25 m house with a 2.6 m x 2.5 m bay (6.5 m²) on its east wall, four nodes.
    let nodes = [
        (1, 0.0, 0.0),
        (2, 20.0, 0.0),
        (3, 20.0, 10.0),
        (4, 22.6, 10.0),
        (5, 22.6, 12.5),
        (6, 20.0, 12.5),
        (7, 20.0, 25.0),
        (8, 0.0, 25.0),
    ];
    for shape in [
        "flat",
        "gabled",
        "hipped",
        "pyramidal",
        "skillion",
        "mansard",
    ] {
        let house = record(
            OsmId::Way(3),
            false,
            ring(&nodes),
            vec![],
            &[
                ("building", "house"),
                ("height", "10"),
                ("roof:shape", shape),
                ("roof:height", "3"),
            ],
        );
        let s = scene(&[&house]);
        let drawn = floors(&s)["way/3"];
        assert!(close(drawn, 506.5), "{shape}: {drawn}");
        assert_eq!(s.buildings.area_lost_ids, vec![], "{shape}");
        assert_strict_solid(&s, shape);
    }
}

/// Pairs of wall triangles of two buildings that lie in one plane, face the same way and
/// overlap: the walls a renderer flickers between.
#[allow(clippy::type_complexity)]
fn coincident_walls(scene: &Scene) -> usize {
    use geo::{Area, BooleanOps, polygon};
    let m = &scene.mesh;
    let walls: Vec<(u32, [f64; 3], f64, [[f64; 2]; 3])> = m
        .triangles
        .iter()
        .enumerate()
        .filter(|(t, _)| m.styles[*t].material == Material::Wall)
        .filter_map(|(t, tri)| {
            let [a, b, c] = m.corners(*tri);
            let (u, v) = (
                [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
            );
            let n = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            (len > 1e-9).then(|| {
                let n = n.map(|x| x / len);
                let d = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
                // In the wall's plane: along it (horizontal) and up.
                let along = |p: [f64; 3]| [-n[1] * p[0] + n[0] * p[1], p[2]];
                (m.styles[t].feature, n, d, [along(a), along(b), along(c)])
            })
        })
        .collect();
    let mut pairs = 0;
    for (i, x) in walls.iter().enumerate() {
        for y in &walls[i + 1..] {
            let same_plane = x.0 != y.0
                && (0..3).all(|k| (x.1[k] - y.1[k]).abs() < 1e-6)
                && (x.2 - y.2).abs() < 1e-6;
            if !same_plane {
                continue;
            }
            let tri = |t: &[[f64; 2]; 3]| polygon![(x: t[0][0], y: t[0][1]), (x: t[1][0], y: t[1][1]), (x: t[2][0], y: t[2][1])];
            if tri(&x.3).intersection(&tri(&y.3)).unsigned_area() > 1e-6 {
                pairs += 1;
            }
        }
    }
    pairs
}

#[test]
fn a_building_drawn_over_another_is_cut_out_of_it_and_no_walls_coincide() {
    // A 10 m x 10 m, 6 m house, and over its south part a 10 m x 6 m, 9 m building sharing its
    // nodes 1 and 2 (and so its south wall and part of its west and east walls).
    let house = record(
        OsmId::Way(10),
        false,
        ring(&[
            (1, 0.0, 0.0),
            (2, 10.0, 0.0),
            (3, 10.0, 10.0),
            (4, 0.0, 10.0),
        ]),
        vec![],
        &[("building", "house"), ("height", "6")],
    );
    let over = record(
        OsmId::Way(11),
        false,
        ring(&[(1, 0.0, 0.0), (2, 10.0, 0.0), (5, 10.0, 6.0), (6, 0.0, 6.0)]),
        vec![],
        &[("building", "yes"), ("height", "9")],
    );
    let before = scene(&[&house]);
    assert_eq!(coincident_walls(&before), 0);
    let s = scene(&[&house, &over]);
    let f = floors(&s);
    assert!(
        close(f["way/10"], 40.0) && close(f["way/11"], 60.0),
        "{f:?}"
    );
    assert_eq!(repairs(&s), vec![("way/10".to_owned(), "overlap_cut_out")]);
    assert_eq!(s.buildings.area_lost_ids, vec![]);
    assert_eq!(coincident_walls(&s), 0);
    assert_strict_solid(&s, "over");
}

#[test]
fn overlapping_outlines_sharing_a_node_keep_the_smaller_whole() {
    // A 10 m x 10 m house; a 10 m x 6 m shed reaching 5 m out of its east side, from node 5 of
    // the house's south wall: 30 m² overlap.
    let house = record(
        OsmId::Way(20),
        false,
        ring(&[
            (1, 0.0, 0.0),
            (5, 5.0, 0.0),
            (2, 10.0, 0.0),
            (3, 10.0, 10.0),
            (4, 0.0, 10.0),
        ]),
        vec![],
        &[("building", "house"), ("height", "6")],
    );
    let shed = record(
        OsmId::Way(21),
        false,
        ring(&[(5, 5.0, 0.0), (7, 15.0, 0.0), (8, 15.0, 6.0), (9, 5.0, 6.0)]),
        vec![],
        &[("building", "shed"), ("height", "3")],
    );
    let s = scene(&[&house, &shed]);
    let f = floors(&s);
    assert!(
        close(f["way/20"], 70.0) && close(f["way/21"], 60.0),
        "{f:?}"
    );
    assert_eq!(repairs(&s), vec![("way/20".to_owned(), "overlap_cut_out")]);
    assert_eq!(coincident_walls(&s), 0);
    let c = check_closed(&s.mesh, s.cluster_triangles[0].clone());
    assert!(
        c.open_edges == 0 && c.degenerate == 0 && c.volume > 0.0,
        "{c:?}"
    );
    let solids = check_manifold(&s.mesh, s.cluster_triangles[0].clone()).report;
    assert!(solids.is_strict(), "{c:?} {solids:?}");
}

/// A square house `(x0, y0)` to `(x0 + 10, y0 + 10)`, its corners nodes `first..first + 4`
/// unless a corner is given a shared node.
fn square(id: i64, x0: f64, y0: f64, nodes: [i64; 4], height: &str) -> BuildingRecord {
    record(
        OsmId::Way(id),
        false,
        ring(&[
            (nodes[0], x0, y0),
            (nodes[1], x0 + 10.0, y0),
            (nodes[2], x0 + 10.0, y0 + 10.0),
            (nodes[3], x0, y0 + 10.0),
        ]),
        vec![],
        &[("building", "house"), ("height", height)],
    )
}

/// Checks each building's own triangles as one surface.
fn per_building(scene: &Scene) -> BTreeMap<String, citymesh_core::mesh::ClosedReport> {
    let m = &scene.mesh;
    let mut by_feature: BTreeMap<u32, citymesh_core::mesh::Mesh> = BTreeMap::new();
    for (t, tri) in m.triangles.iter().enumerate() {
        if m.styles[t].feature == citymesh_core::mesh::NO_FEATURE {
            continue;
        }
        let one = by_feature.entry(m.styles[t].feature).or_default();
        let base = one.positions.len() as u32;
        for p in m.corners(*tri) {
            one.push_vertex(p);
        }
        one.push_triangle([base, base + 1, base + 2], m.styles[t]);
    }
    by_feature
        .into_iter()
        .map(|(f, one)| {
            let id = scene.buildings.features[f as usize].id.to_string();
            (id, check_closed(&one, 0..one.triangles.len()))
        })
        .collect()
}

#[test]
fn houses_touching_at_a_corner_line_are_two_strict_solids() {
    // Two 10 m x 10 m houses, 6 m high, meeting diagonally at node 3: by position, the corner
    // line's edge has four triangles.
    let a = square(30, 0.0, 0.0, [1, 2, 3, 4], "6");
    let b = square(31, 10.0, 10.0, [3, 5, 6, 7], "6");
    let s = scene(&[&a, &b]);
    let group = check_closed(&s.mesh, s.cluster_triangles[0].clone());
    assert_eq!(
        (group.open_edges, group.non_manifold_edges),
        (0, 1),
        "{group:?}"
    );
    // Split along that line, each house is its own solid: every edge of each has exactly two
    // triangles, by position, checked on its own triangles.
    let solids = check_manifold(&s.mesh, s.cluster_triangles[0].clone()).report;
    assert_eq!((solids.solids, solids.split_edges), (2, 1), "{solids:?}");
    assert!(solids.is_strict());
    for (id, r) in per_building(&s) {
        assert!(r.is_closed_and_outward(), "{id}: {r:?}");
    }
    for f in &s.buildings.features {
        assert!(
            f.quality.closed && f.quality.strict_manifold,
            "{:?}",
            f.quality
        );
    }
    assert_eq!(coincident_walls(&s), 0);
}

#[test]
fn four_houses_of_two_heights_at_one_corner_report_the_pinch() {
    // Four houses around node 5, the south-west and north-east 10 m, the others 5 m: above
    // 5 m the two tall houses touch along the corner line, and below they are one solid
    // through the low houses. That solid touches itself; no split makes it a 2-manifold, and
    // the record of each of the four says so.
    let sw = square(40, 0.0, 0.0, [1, 2, 5, 4], "10");
    let se = square(41, 10.0, 0.0, [2, 3, 6, 5], "5");
    let ne = square(42, 10.0, 10.0, [5, 6, 8, 7], "10");
    let nw = square(43, 0.0, 10.0, [4, 5, 7, 9], "5");
    let s = scene(&[&sw, &se, &ne, &nw]);
    let range = s.cluster_triangles[0].clone();
    let group = check_closed(&s.mesh, range.clone());
    assert!(group.open_edges == 0 && group.volume > 0.0, "{group:?}");
    let solids = check_manifold(&s.mesh, range).report;
    assert_eq!(
        (
            solids.solids,
            solids.unpaired_edges,
            solids.pinched_vertices
        ),
        (1, 0, 1),
        "{solids:?}"
    );
    for f in &s.buildings.features {
        assert!(
            f.quality.closed && !f.quality.strict_manifold,
            "{:?}",
            f.quality
        );
    }
    // The floors are whole: nothing lost, only the topology is not strict.
    let f = floors(&s);
    assert!(f.values().all(|&a| close(a, 100.0)), "{f:?}");
}

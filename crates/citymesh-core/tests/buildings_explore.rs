mod common;
use citymesh_core::building::clusters;
use citymesh_core::geo::GeoBbox;
use citymesh_core::mesh::check_closed;
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use std::io::Read;

fn bytes(name: &str) -> Vec<u8> {
    let b = std::fs::read(common::data_dir().join("osm").join(name)).unwrap();
    if !name.ends_with(".gz") {
        return b;
    }
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(&b[..])
        .read_to_end(&mut out)
        .unwrap();
    out
}

#[test]
fn explore() {
    for (file, dem) in [
        ("karlsruhe-kirchfeld.osm.pbf", vec!["N49E008.hgt"]),
        ("karlsruhe-kit-nord.osm.pbf", vec!["N49E008.hgt"]),
        ("tram-junction.osm.pbf", vec!["N49E008.hgt"]),
        ("nuremberg-laufamholz.osm", vec!["N49E011.hgt"]),
        ("san-francisco.overpass.json.gz", vec![]),
    ] {
        let b = read_buildings(&bytes(file)).unwrap();
        let cl = clusters(&b.buildings);
        let groups: Vec<Vec<_>> = cl
            .iter()
            .map(|c| c.iter().map(|&i| &b.buildings[i]).collect())
            .collect();
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for r in &b.buildings {
            for n in r.outers.iter().flat_map(|r| &r.nodes) {
                x0 = x0.min(n.lon);
                y0 = y0.min(n.lat);
                x1 = x1.max(n.lon);
                y1 = y1.max(n.lat);
            }
        }
        let bbox = GeoBbox::new(x0, y0, x1, y1).unwrap();
        let model = common::model(&dem);
        let t = std::time::Instant::now();
        let scene = Scene::new(&model, &bbox, &groups, Border::Whole);
        let el = t.elapsed();
        let mut bad = 0;
        for (i, r) in scene.cluster_triangles.iter().enumerate() {
            let rep = check_closed(&scene.mesh, r.clone());
            if rep.open_edges > 0 || rep.degenerate > 0 || rep.volume <= 0.0 {
                bad += 1;
                if bad <= 5 {
                    eprintln!(
                        "{file} cluster {i} ids {:?}: {rep:?}",
                        groups[i]
                            .iter()
                            .map(|r| r.id.to_string())
                            .collect::<Vec<_>>()
                    );
                }
            }
        }
        eprintln!(
            "{file}: {} clusters, bad {bad}, {:?}, tris {}, stats {:?}",
            groups.len(),
            el,
            scene.mesh.triangles.len(),
            scene.buildings.skipped
        );
        eprintln!(
            "   shapes {:?} shared {} dropped {} covered {}",
            scene.buildings.roof_shapes,
            scene.buildings.shared_walls,
            scene.buildings.dropped_constraints,
            scene.buildings.outlines_covered_by_parts
        );
    }
}

#[test]
fn debug_one() {
    let file = std::env::var("F").unwrap_or("nuremberg-laufamholz.osm".into());
    let ids: Vec<String> = std::env::var("IDS")
        .unwrap_or("way/77815637,way/404460944".into())
        .split(',')
        .map(String::from)
        .collect();
    let b = read_buildings(&bytes(&file)).unwrap();
    let recs: Vec<_> = b
        .buildings
        .iter()
        .filter(|r| ids.contains(&r.id.to_string()))
        .collect();
    for r in &recs {
        eprintln!(
            "{} {:?} nodes {:?}",
            r.id,
            r.tags,
            r.outers[0]
                .nodes
                .iter()
                .map(|n| n.id.unwrap_or(0))
                .collect::<Vec<_>>()
        );
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    let all: Vec<_> = if std::env::var("FULL").is_ok() {
        b.buildings.iter().collect()
    } else {
        recs.clone()
    };
    for r in &all {
        for n in r.outers.iter().flat_map(|r| &r.nodes) {
            x0 = x0.min(n.lon);
            y0 = y0.min(n.lat);
            x1 = x1.max(n.lon);
            y1 = y1.max(n.lat);
        }
    }
    let bbox = GeoBbox::new(x0, y0, x1, y1).unwrap();
    let dem = if file.contains("nuremberg") {
        vec!["N49E011.hgt"]
    } else {
        vec!["N49E008.hgt"]
    };
    let model = common::model(&dem);
    let scene = Scene::new(&model, &bbox, &[recs.clone()], Border::Whole);
    let r = scene.cluster_triangles[0].clone();
    eprintln!("{:?}", check_closed(&scene.mesh, r.clone()));
    // print degenerate and open edge triangles
    use std::collections::HashMap;
    let key = |p: [f64; 3]| p.map(|c| (c / 1e-6).round() as i64);
    let mut directed: HashMap<([i64; 3], [i64; 3]), Vec<usize>> = HashMap::new();
    for t in r.clone() {
        let c = scene.mesh.corners(scene.mesh.triangles[t]);
        let ids = c.map(|p| key(p));
        let (u, w) = (
            [c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]],
            [c[2][0] - c[0][0], c[2][1] - c[0][1], c[2][2] - c[0][2]],
        );
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let a2 = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2] || a2 < 1e-8 {
            eprintln!("degenerate {:?} {:?}", scene.mesh.styles[t].material, c);
        }
        for k in 0..3 {
            directed
                .entry((key(c[k]), key(c[(k + 1) % 3])))
                .or_default()
                .push(t);
        }
    }
    for ((a, b), ts) in &directed {
        let back = directed.get(&(*b, *a)).map_or(0, |v| v.len());
        let nm = ts.len() + back > 2 && a < b;
        if back != ts.len() || nm {
            eprintln!(
                "edge {:?} -> {:?} x{} back {} tris {:?}",
                a,
                b,
                ts.len(),
                back,
                ts.iter()
                    .map(|&t| (
                        scene.mesh.styles[t].material,
                        scene.mesh.corners(scene.mesh.triangles[t])
                    ))
                    .collect::<Vec<_>>()
            );
        }
    }
}

#[test]
fn debug_divide() {
    use citymesh_core::building::{
        axes::RoofAxes, boundary::divide, footprint::*, roof::RoofShape, roof_surface::RoofSurface,
        tags::BuildingTags,
    };
    use citymesh_core::geo::LocalFrame;
    let b = read_buildings(&bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for r in &b.buildings {
        for n in r.outers.iter().flat_map(|r| &r.nodes) {
            x0 = x0.min(n.lon);
            y0 = y0.min(n.lat);
            x1 = x1.max(n.lon);
            y1 = y1.max(n.lat);
        }
    }
    let frame = LocalFrame::new((x0 + x1) / 2.0, (y0 + y1) / 2.0, 0.0);
    let r = b
        .buildings
        .iter()
        .find(|r| r.id.to_string() == "way/96784667")
        .unwrap();
    let ring = FootprintRing::new(
        r.outers[0]
            .nodes
            .iter()
            .map(|n| {
                let p = frame.to_local(n.lon, n.lat, 0.0);
                [p[0], p[1]]
            })
            .collect(),
        r.outers[0]
            .nodes
            .iter()
            .map(|n| NodeKey::Osm(n.id.unwrap()))
            .collect(),
    );
    let f = Footprint::new(ring, vec![]).unwrap();
    eprintln!("{:?}", f.outer);
    let axes = RoofAxes::of_ring(&f.outer.points).unwrap().long_first();
    let t = BuildingTags::read(&r.tags);
    let s = RoofSurface::new(
        RoofShape::Pyramidal,
        axes,
        t.orientation,
        &f.outer.points,
        None,
        None,
    )
    .with_heights(10.0, 3.0);
    let segs = s.dividing_segments();
    eprintln!("segs {segs:?}");
    let d = divide(&f, &segs);
    eprintln!("{d:?}");
}

#[test]
fn debug_l_mansard() {
    use citymesh_core::geo::LocalFrame;
    use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode};
    let bbox = GeoBbox::new(8.39, 48.99, 8.41, 49.01).unwrap();
    let (lon, lat) = bbox.center();
    let f = LocalFrame::new(lon, lat, 0.0);
    let pts = [
        [0.0, 0.0],
        [10.513410602768317, 0.0],
        [10.513410602768317, 7.310330883203299],
        [7.310330883203299, 7.310330883203299],
        [7.310330883203299, 10.513410602768317],
        [0.0, 10.513410602768317],
    ];
    let nodes = pts
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (lon, lat, _) = f.to_geographic([p[0], p[1], 0.0]);
            RingNode {
                id: Some(i as i64 + 1),
                lon,
                lat,
            }
        })
        .collect();
    let tags = [
        ("building", "yes"),
        ("height", "2"),
        ("roof:height", "11.39"),
        ("roof:shape", "mansard"),
    ]
    .iter()
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    let rec = BuildingRecord {
        id: OsmId::Way(1),
        is_part: false,
        outers: vec![Ring { nodes }],
        inners: vec![],
        tags,
    };
    let scene = Scene::new(
        &citymesh_core::terrain::ElevationModel::default(),
        &bbox,
        &[vec![&rec]],
        Border::Whole,
    );
    eprintln!(
        "{:?}",
        check_closed(&scene.mesh, scene.cluster_triangles[0].clone())
    );
    for (t, s) in scene.mesh.triangles.iter().zip(&scene.mesh.styles) {
        let c = scene.mesh.corners(*t);
        let (u, w) = (
            [c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]],
            [c[2][0] - c[0][0], c[2][1] - c[0][1], c[2][2] - c[0][2]],
        );
        let n = [
            u[1] * w[2] - u[2] * w[1],
            u[2] * w[0] - u[0] * w[2],
            u[0] * w[1] - u[1] * w[0],
        ];
        let a2 = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if a2 < 1e-8 {
            eprintln!("degenerate {:?} {:?} {a2}", s.material, c);
        }
    }
}

#[test]
fn debug_row() {
    use citymesh_core::geo::LocalFrame;
    use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode};
    let bbox = GeoBbox::new(8.39, 48.99, 8.41, 49.01).unwrap();
    let (lon, lat) = bbox.center();
    let f = LocalFrame::new(lon, lat, 0.0);
    let depth = 6.0;
    let widths = [4.0, 4.0];
    let angle: f64 = 0.0;
    let specs = [
        ("flat", false, 22.45163028140739, 0.0, 7.292684085193916),
        (
            "gambrel",
            true,
            8.347059119091218,
            4.300058655031569,
            4.332374044407356,
        ),
    ];
    let mut recs = vec![];
    let mut x = 0.0;
    for (i, (shape, across, h, rh, mh)) in specs.iter().enumerate() {
        let w = widths[i];
        let (sn, cs) = angle.sin_cos();
        let pts: Vec<[f64; 2]> = [[x, 0.0], [x + w, 0.0], [x + w, depth], [x, depth]]
            .iter()
            .map(|p: &[f64; 2]| [p[0] * cs - p[1] * sn, p[0] * sn + p[1] * cs])
            .collect();
        x += w;
        let ids = [
            10 * i as i64,
            10 * (i as i64 + 1),
            10 * (i as i64 + 1) + 1,
            10 * i as i64 + 1,
        ];
        let nodes = pts
            .iter()
            .zip(ids)
            .map(|(p, id)| {
                let (lon, lat, _) = f.to_geographic([p[0], p[1], 0.0]);
                RingNode {
                    id: Some(id),
                    lon,
                    lat,
                }
            })
            .collect();
        let mut tags: citymesh_core::osm::Tags = [
            ("building", "yes".to_string()),
            ("height", h.to_string()),
            ("roof:height", rh.to_string()),
            ("roof:shape", shape.to_string()),
            ("min_height", mh.to_string()),
            ("roof:direction", "90".to_string()),
        ]
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect();
        if *across {
            tags.insert("roof:orientation".into(), "across".into());
        }
        recs.push(BuildingRecord {
            id: OsmId::Way(i as i64 + 1),
            is_part: false,
            outers: vec![Ring { nodes }],
            inners: vec![],
            tags,
        });
    }
    let refs: Vec<_> = recs.iter().collect();
    let scene = Scene::new(
        &citymesh_core::terrain::ElevationModel::default(),
        &bbox,
        &[refs],
        Border::Whole,
    );
    eprintln!(
        "{:?}",
        check_closed(&scene.mesh, scene.cluster_triangles[0].clone())
    );
    use std::collections::HashMap;
    let key = |p: [f64; 3]| p.map(|c| (c / 1e-6).round() as i64);
    let mut directed: HashMap<([i64; 3], [i64; 3]), Vec<usize>> = HashMap::new();
    for t in scene.cluster_triangles[0].clone() {
        let c = scene.mesh.corners(scene.mesh.triangles[t]);
        {
            let (u, w) = (
                [c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]],
                [c[2][0] - c[0][0], c[2][1] - c[0][1], c[2][2] - c[0][2]],
            );
            let n = [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ];
            let a2 = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if a2 < 1e-8 {
                eprintln!(
                    "degenerate {:?} {:?} {a2}",
                    scene.mesh.styles[t].material, c
                );
            }
        }
        for k in 0..3 {
            directed
                .entry((key(c[k]), key(c[(k + 1) % 3])))
                .or_default()
                .push(t);
        }
    }
    for ((a, b), ts) in &directed {
        let back = directed.get(&(*b, *a)).map_or(0, |v| v.len());
        if back != ts.len() || true {
            let _ = 0;
        }
        if back != ts.len() {
            eprintln!(
                "edge {:?} -> {:?} x{} back {} {:?}",
                a,
                b,
                ts.len(),
                back,
                ts.iter()
                    .map(|&t| scene.mesh.styles[t].material)
                    .collect::<Vec<_>>()
            );
        }
    }
}

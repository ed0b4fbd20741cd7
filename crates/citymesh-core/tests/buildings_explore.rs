mod common;
use citymesh_core::building::clusters;
use citymesh_core::geo::GeoBbox;
use citymesh_core::mesh::check_closed;
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use std::io::Read;

fn bytes(name: &str) -> Vec<u8> {
    let b = std::fs::read(common::data_dir().join("osm").join(name)).unwrap();
    if !name.ends_with(".gz") { return b; }
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(&b[..]).read_to_end(&mut out).unwrap();
    out
}

#[test]
fn explore() {
    for (file, dem) in [("karlsruhe-kirchfeld.osm.pbf", vec!["N49E008.hgt"]), ("karlsruhe-kit-nord.osm.pbf", vec!["N49E008.hgt"]), ("tram-junction.osm.pbf", vec!["N49E008.hgt"]), ("nuremberg-laufamholz.osm", vec!["N49E011.hgt"]), ("san-francisco.overpass.json.gz", vec![])] {
        let b = read_buildings(&bytes(file)).unwrap();
        let cl = clusters(&b.buildings);
        let groups: Vec<Vec<_>> = cl.iter().map(|c| c.iter().map(|&i| &b.buildings[i]).collect()).collect();
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for r in &b.buildings { for n in r.outers.iter().flat_map(|r| &r.nodes) { x0 = x0.min(n.lon); y0 = y0.min(n.lat); x1 = x1.max(n.lon); y1 = y1.max(n.lat);} }
        let bbox = GeoBbox::new(x0, y0, x1, y1).unwrap();
        let model = common::model(&dem);
        let t = std::time::Instant::now();
        let scene = Scene::new(&model, &bbox, &groups, Border::Whole);
        let el = t.elapsed();
        let mut bad = 0;
        for (i, r) in scene.cluster_triangles.iter().enumerate() {
            let rep = check_closed(&scene.mesh, r.clone());
            if !rep.is_closed_and_outward() {
                bad += 1;
                if bad <= 5 { eprintln!("{file} cluster {i} ids {:?}: {rep:?}", groups[i].iter().map(|r| r.id.to_string()).collect::<Vec<_>>()); }
            }
        }
        eprintln!("{file}: {} clusters, bad {bad}, {:?}, tris {}, stats {:?}", groups.len(), el, scene.mesh.triangles.len(), scene.buildings.skipped);
        eprintln!("   shapes {:?} shared {} dropped {} covered {}", scene.buildings.roof_shapes, scene.buildings.shared_walls, scene.buildings.dropped_constraints, scene.buildings.outlines_covered_by_parts);
    }
}

#[test]
fn debug_one() {
    let file = std::env::var("F").unwrap_or("nuremberg-laufamholz.osm".into());
    let ids: Vec<String> = std::env::var("IDS").unwrap_or("way/77815637,way/404460944".into()).split(',').map(String::from).collect();
    let b = read_buildings(&bytes(&file)).unwrap();
    let recs: Vec<_> = b.buildings.iter().filter(|r| ids.contains(&r.id.to_string())).collect();
    for r in &recs { eprintln!("{} {:?} nodes {:?}", r.id, r.tags, r.outers[0].nodes.iter().map(|n| n.id.unwrap_or(0)).collect::<Vec<_>>()); }
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for r in &recs { for n in r.outers.iter().flat_map(|r| &r.nodes) { x0 = x0.min(n.lon); y0 = y0.min(n.lat); x1 = x1.max(n.lon); y1 = y1.max(n.lat);} }
    let bbox = GeoBbox::new(x0, y0, x1, y1).unwrap();
    let dem = if file.contains("nuremberg") { vec!["N49E011.hgt"] } else { vec!["N49E008.hgt"] };
    let model = common::model(&dem);
    let scene = Scene::new(&model, &bbox, &[recs.clone()], Border::Whole);
    let r = scene.cluster_triangles[0].clone();
    eprintln!("{:?}", check_closed(&scene.mesh, r.clone()));
    // print degenerate and open edge triangles
    use std::collections::HashMap;
    let key = |p: [f64;3]| p.map(|c| (c / 1e-6).round() as i64);
    let mut directed: HashMap<([i64;3],[i64;3]), Vec<usize>> = HashMap::new();
    for t in r.clone() {
        let c = scene.mesh.corners(scene.mesh.triangles[t]);
        for k in 0..3 { directed.entry((key(c[k]), key(c[(k+1)%3]))).or_default().push(t); }
    }
    for ((a, b), ts) in &directed {
        let back = directed.get(&(*b, *a)).map_or(0, |v| v.len());
        if back != ts.len() {
            eprintln!("edge {:?} -> {:?} x{} back {} tris {:?}", a, b, ts.len(), back, ts.iter().map(|&t| (scene.mesh.styles[t].material, scene.mesh.corners(scene.mesh.triangles[t]))).collect::<Vec<_>>());
        }
    }
}

//! GLB bytes per building on the whole Karlsruhe-Kirchfeld scene (3,018 buildings and parts),
//! against the goals of the speed-and-bytes work: plain at most 1,000 B per building, meshopt at
//! most 350 B, in the local frame citymesh serves scenes and XYZ tiles in.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use citymesh_core::building::set::BuildingSet;
use citymesh_core::mesh::{Encoding, Placement};
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;
use common::{model, osm_bytes};

/// The Kirchfeld buildings and the ground model under them.
fn kirchfeld() -> (BuildingSet, ElevationModel) {
    let set = BuildingSet::new(
        read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    (set, model(&["N49E008.hgt"]))
}

#[test]
fn kirchfeld_bytes_per_building_meet_the_goals() {
    let (set, m) = kirchfeld();
    let bbox = set.extent().unwrap();
    let scene = Scene::new(&m, &bbox, &set.groups(), Border::Whole);
    assert_eq!(scene.buildings.generated, 3018);
    let per_building = |e: Encoding| {
        let glb = scene.encode(Placement::LocalEnu, e);
        // Every encoding keeps (nearly) every triangle of the mesh.
        assert!(
            glb.triangles * 100 >= scene.mesh.triangles.len() * 96,
            "{e}"
        );
        glb.bytes.len() / scene.buildings.generated
    };
    let (plain, quantized, meshopt) = (
        per_building(Encoding::Plain),
        per_building(Encoding::Quantized),
        per_building(Encoding::Meshopt),
    );
    println!("bytes per building: plain {plain}, quantized {quantized}, meshopt {meshopt}");
    assert!(plain <= 1000, "plain: {plain} B per building");
    assert!(meshopt <= 350, "meshopt: {meshopt} B per building");
    assert!(meshopt < quantized && quantized < plain);
}

#[test]
fn groups_built_on_several_threads_make_the_same_scene() {
    let (set, m) = kirchfeld();
    let bbox = set.extent().unwrap();
    let groups = set.groups();
    let serial = Scene::new(&m, &bbox, &groups, Border::Whole);
    for workers in [2, 3, 8] {
        let parallel =
            Scene::new_with_workers(&m, &bbox, &groups, Border::Whole, &|| false, workers).unwrap();
        assert_eq!(parallel.mesh, serial.mesh, "{workers} workers");
        assert_eq!(parallel.buildings, serial.buildings);
        assert_eq!(parallel.cluster_triangles, serial.cluster_triangles);
        assert_eq!(parallel.to_glb(), serial.to_glb());
    }
    // A stop asked for ends every thread's run: no scene.
    assert!(Scene::new_with_workers(&m, &bbox, &groups, Border::Whole, &|| true, 2).is_none());
}

/// The JSON and binary chunks of a GLB.
fn chunks(glb: &[u8]) -> (serde_json::Value, &[u8]) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let bin = glb.get(20 + json_len + 8..).unwrap_or_default();
    (json, bin)
}

/// The bytes of buffer view `k` (of buffer 0, the GLB's own).
fn view<'a>(json: &serde_json::Value, bin: &'a [u8], k: u64) -> &'a [u8] {
    let v = &json["bufferViews"][k as usize];
    assert_eq!(v["buffer"], 0);
    let at = v["byteOffset"].as_u64().unwrap_or(0) as usize;
    &bin[at..at + v["byteLength"].as_u64().unwrap() as usize]
}

/// The f32 values of accessor `k` (SCALAR or VEC3, tightly packed or with a stride).
fn floats(json: &serde_json::Value, bin: &[u8], k: u64) -> Vec<Vec<f32>> {
    let a = &json["accessors"][k as usize];
    assert_eq!(a["componentType"], 5126);
    let n = if a["type"] == "VEC3" { 3 } else { 1 };
    let v = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let stride = v["byteStride"].as_u64().unwrap_or(4 * n) as usize;
    let data = view(json, bin, a["bufferView"].as_u64().unwrap());
    let start = a["byteOffset"].as_u64().unwrap_or(0) as usize;
    (0..a["count"].as_u64().unwrap() as usize)
        .map(|i| {
            (0..n as usize)
                .map(|c| {
                    let at = start + i * stride + 4 * c;
                    f32::from_le_bytes(data[at..at + 4].try_into().unwrap())
                })
                .collect()
        })
        .collect()
}

#[test]
fn every_building_vertex_names_its_building_and_its_row_describes_it() {
    use citymesh_core::osm::OsmId;
    let (set, m) = kirchfeld();
    let bbox = set.extent().unwrap();
    let scene = Scene::new(&m, &bbox, &set.groups(), Border::Whole);
    let glb = scene.encode(Placement::LocalEnu, Encoding::Plain);
    let (json, bin) = chunks(&glb.bytes);
    // One row per generated building, its OSM type and id in its columns.
    let table = &json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
    assert_eq!(table["count"], 3018);
    assert_eq!(table["class"], "building");
    let ids: Vec<i64> = view(
        &json,
        bin,
        table["properties"]["osm_id"]["values"].as_u64().unwrap(),
    )
    .chunks_exact(8)
    .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
    .collect();
    let want: Vec<i64> = scene
        .buildings
        .features
        .iter()
        .map(|f| match f.id {
            OsmId::Way(id) | OsmId::Relation(id) => id,
        })
        .collect();
    assert_eq!(ids, want);
    // Each building's vertices lie in its footprint's box (local frame: x east, -z north).
    let records: std::collections::HashMap<OsmId, _> = set
        .groups()
        .into_iter()
        .flatten()
        .map(|r| (r.id, r))
        .collect();
    let boxes: Vec<[f64; 4]> = scene
        .buildings
        .features
        .iter()
        .map(|f| {
            let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
            for n in records[&f.id].outers.iter().flat_map(|r| &r.nodes) {
                let p = scene.frame.to_local(n.lon, n.lat, 0.0);
                b = [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ];
            }
            b
        })
        .collect();
    let mut seen = vec![0usize; boxes.len()];
    let mut ground = 0;
    for p in json["meshes"][0]["primitives"].as_array().unwrap() {
        let positions = floats(&json, bin, p["attributes"]["POSITION"].as_u64().unwrap());
        let Some(k) = p["attributes"]["_FEATURE_ID_0"].as_u64() else {
            assert!(p.get("extensions").is_none());
            ground += positions.len();
            continue;
        };
        let ext = &p["extensions"]["EXT_mesh_features"]["featureIds"][0];
        assert_eq!(ext["featureCount"], 3018);
        assert_eq!(ext["propertyTable"], 0);
        let features = floats(&json, bin, k);
        for (pos, f) in positions.iter().zip(&features) {
            let f = f[0] as usize;
            let b = boxes[f];
            let (x, y) = (f64::from(pos[0]), -f64::from(pos[2]));
            assert!(
                x >= b[0] - 0.01 && x <= b[2] + 0.01 && y >= b[1] - 0.01 && y <= b[3] + 0.01,
                "a vertex of feature {f} ({}) at {x}, {y} lies outside its footprint {b:?}",
                scene.buildings.features[f].id
            );
            seen[f] += 1;
        }
    }
    assert!(ground > 0, "the ground has vertices without features");
    assert_eq!(
        seen.iter().filter(|&&n| n == 0).count(),
        0,
        "buildings without vertices"
    );
    // The other encodings carry the same table.
    for e in [Encoding::Quantized, Encoding::Meshopt] {
        let other = scene.encode(Placement::LocalEnu, e);
        let (j, b) = chunks(&other.bytes);
        let t = &j["extensions"]["EXT_structural_metadata"];
        assert_eq!(t["propertyTables"][0]["count"], 3018, "{e}");
        let k = t["propertyTables"][0]["properties"]["osm_id"]["values"]
            .as_u64()
            .unwrap();
        assert_eq!(
            view(&j, b, k),
            view(
                &json,
                bin,
                table["properties"]["osm_id"]["values"].as_u64().unwrap()
            ),
            "{e}"
        );
        assert!(
            j["extensionsUsed"]
                .as_array()
                .unwrap()
                .contains(&"EXT_mesh_features".into())
        );
    }
}

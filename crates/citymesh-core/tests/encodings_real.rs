//! GLB bytes per building on the whole Karlsruhe-Kirchfeld scene (3,019 buildings and parts),
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
    assert_eq!(scene.buildings.generated, 3019);
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

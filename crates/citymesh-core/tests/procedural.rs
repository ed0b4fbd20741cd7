//! Procedural cities through the generator: their definitions survive GeoJSON exactly, and every
//! volume they give is closed and outward-facing.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::building::set::BuildingSet;
use citymesh_core::geojson::{GeoJsonLimits, read_geojson, write_geojson};
use citymesh_core::mesh::check_closed;
use citymesh_core::procedural::{ProceduralParams, generate_city};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;

#[test]
fn definitions_survive_geojson_exactly() {
    let p = ProceduralParams {
        seed: 11,
        width: 700.0,
        height: 500.0,
        ..Default::default()
    };
    let city = generate_city(&p).unwrap();
    let back = read_geojson(
        &write_geojson(&city.records, &city.bbox),
        GeoJsonLimits::default(),
    )
    .unwrap();
    assert_eq!(back.bbox, Some(city.bbox));
    assert_eq!(back.records, city.records);
}

#[test]
fn every_procedural_volume_is_closed_and_outward() {
    for seed in 1..=4 {
        let p = ProceduralParams {
            seed,
            complexity: 7,
            ..Default::default()
        };
        let city = generate_city(&p).unwrap();
        let set = BuildingSet::new(city.records.clone());
        let scene = Scene::new(
            &ElevationModel::default(),
            &city.bbox,
            &set.groups(),
            Border::Whole,
        );
        assert_eq!(scene.buildings.skipped.len(), 0, "seed {seed}");
        // Every record is generated but for tower outlines, which their parts cover.
        let outlines = city
            .records
            .iter()
            .filter(|r| !r.is_part && r.tags["citymesh:layout"] == "tower")
            .count();
        assert_eq!(scene.buildings.outlines_covered_by_parts, outlines);
        assert_eq!(scene.buildings.generated + outlines, city.records.len());
        for range in &scene.cluster_triangles {
            let r = check_closed(&scene.mesh, range.clone());
            assert!(
                r.open_edges == 0 && r.degenerate == 0 && r.volume > 0.0,
                "seed {seed}: {r:?}"
            );
        }
    }
}

//! The whole Karlsruhe-Kirchfeld scene (2,995 buildings and 31 parts on the SRTM ground of their
//! extent), from parsed OSM records to GLB bytes, and the OSM parsing before it.
//! Reads `osm/karlsruhe-kirchfeld.osm.pbf`, `osm/karlsruhe-kirchfeld.overpass.json` and
//! `dem/N49E008.hgt` from `CITYMESH_DATA_DIR`
//! (default `../shared/data`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::building::clusters;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::mesh::{Encoding, Placement, check_closed, check_manifold};
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::{ElevationModel, HgtTile};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;

// The allocator the server runs with (src/main.rs): without it, glibc returns the scene's buffers
// to the kernel after each scene and faults them back in the next one.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn read(name: &str) -> Vec<u8> {
    let dir = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    );
    let path = dir.join(name);
    std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (set CITYMESH_DATA_DIR)", path.display()))
}

/// Kirchfeld's ground, its OSM PBF and its buildings.
fn kirchfeld_data() -> (ElevationModel, Vec<u8>, BuildingSet) {
    let model = ElevationModel::new(vec![Arc::new(
        HgtTile::from_bytes(49, 8, &read("dem/N49E008.hgt")).unwrap(),
    )]);
    let pbf = read("osm/karlsruhe-kirchfeld.osm.pbf");
    let set = BuildingSet::new(read_buildings(&pbf).unwrap().buildings);
    (model, pbf, set)
}

fn kirchfeld(c: &mut Criterion) {
    let (model, pbf, set) = kirchfeld_data();
    let groups = set.groups();
    let bbox = set.extent().unwrap();

    let scene = Scene::new(&model, &bbox, &groups, Border::Whole);
    eprintln!(
        "kirchfeld scene: {} buildings generated, {} vertices, {} triangles (mesh)",
        scene.buildings.generated,
        scene.mesh.positions.len(),
        scene.mesh.triangles.len(),
    );
    for encoding in Encoding::ALL {
        for placement in [Placement::LocalEnu, Placement::Ecef] {
            let glb = scene.encode(placement, encoding);
            eprintln!(
                "  {encoding} {placement:?}: {} bytes, {} B per building, {} vertices, {} triangles",
                glb.bytes.len(),
                glb.bytes.len() / scene.buildings.generated,
                glb.vertices,
                glb.triangles
            );
        }
    }

    let build = || {
        Scene::new(
            black_box(&model),
            black_box(&bbox),
            black_box(&groups),
            Border::Whole,
        )
    };
    c.bench_function("kirchfeld_scene_to_glb", |b| b.iter(|| build().to_glb()));
    c.bench_function("kirchfeld_scene_mesh_only", |b| b.iter(build));
    // Over every group: the quality record's check, which the mesh above includes (the solids,
    // split where volumes touch along a line), and the closedness check tests use.
    let groups_checked = |check: &dyn Fn(std::ops::Range<usize>) -> usize| {
        scene
            .cluster_triangles
            .iter()
            .map(|r| check(r.clone()))
            .sum::<usize>()
    };
    c.bench_function("kirchfeld_groups_solids", |b| {
        b.iter(|| groups_checked(&|r| check_manifold(&scene.mesh, r).report.solids));
    });
    c.bench_function("kirchfeld_groups_closed", |b| {
        b.iter(|| groups_checked(&|r| check_closed(&scene.mesh, r).open_edges));
    });
    // The same scene with its groups shared among two threads (as `citymesh scene` does).
    c.bench_function("kirchfeld_scene_to_glb_2_workers", |b| {
        b.iter(|| {
            Scene::new_with_workers(
                black_box(&model),
                black_box(&bbox),
                black_box(&groups),
                Border::Whole,
                &|| false,
                2,
            )
            .map(|s| s.to_glb())
        });
    });
    for encoding in Encoding::ALL {
        c.bench_function(&format!("kirchfeld_encode_{encoding}"), |b| {
            b.iter(|| scene.encode(Placement::LocalEnu, black_box(encoding)).bytes);
        });
    }
    // The Overpass JSON `citymesh scene` and Overpass answers bring: elements taken over as
    // they are parsed, then assembled into buildings.
    let json = read("osm/karlsruhe-kirchfeld.overpass.json");
    c.bench_function("kirchfeld_overpass_json_read", |b| {
        b.iter(|| read_buildings(black_box(&json)).unwrap().buildings.len());
    });
    c.bench_function("kirchfeld_pbf_parse_and_cluster", |b| {
        b.iter(|| {
            let osm = read_buildings(black_box(&pbf)).unwrap();
            clusters(&osm.buildings).len()
        });
    });
}

/// Roofs over the straight skeleton: the Kirchfeld scene with every hipped, gabled and
/// pyramidal roof laid over the virtual rectangle, then over the skeleton (the ratio is the
/// skeleton's cost), and the skeleton of one U-shaped and one 64-vertex outline alone.
fn roof_methods(c: &mut Criterion) {
    use citymesh_core::building::RoofMethod;
    use citymesh_core::building::straight_skeleton::Skeleton;
    use citymesh_core::scene::SceneRules;
    let (model, _, set) = kirchfeld_data();
    let groups = set.groups();
    let bbox = set.extent().unwrap();
    for method in [
        RoofMethod::Rectangle,
        RoofMethod::Auto,
        RoofMethod::Skeleton,
    ] {
        let rules = SceneRules {
            roof_method: method,
            ..SceneRules::new(Border::Whole)
        };
        c.bench_function(&format!("kirchfeld_scene_roofs_{}", method.name()), |b| {
            b.iter(|| Scene::new_with_rules(black_box(&model), &bbox, &groups, rules));
        });
    }
    let u: Vec<[f64; 2]> = vec![
        [0.0, 0.0],
        [20.0, 0.0],
        [20.0, 15.0],
        [14.0, 15.0],
        [14.0, 6.0],
        [6.0, 6.0],
        [6.0, 15.0],
        [0.0, 15.0],
    ];
    c.bench_function("straight_skeleton_u", |b| {
        b.iter(|| Skeleton::of(&[black_box(&u)]).unwrap().nodes.len());
    });
    // Regular stars: half their vertices reflex, every event at once (the worst case: the
    // exact simulation fails and the outline is shaken).
    for n in [64, 128] {
        let star: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let a = k as f64 / n as f64 * std::f64::consts::TAU;
                let r = if k % 2 == 0 { 30.0 } else { 22.0 };
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        c.bench_function(&format!("straight_skeleton_star_{n}"), |b| {
            b.iter(|| Skeleton::of(&[black_box(&star)]).unwrap().nodes.len());
        });
    }
}

criterion_group!(benches, kirchfeld, roof_methods);
criterion_main!(benches);

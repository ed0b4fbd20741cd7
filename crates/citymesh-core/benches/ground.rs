//! The ground of a 2 km x 2 km box over Karlsruhe, from the parsed DEM to GLB bytes, and reading
//! the SRTM file.
//! Reads `N49E008.hgt` from `CITYMESH_DATA_DIR` (default `../shared/data`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::geo::{GeoBbox, LocalFrame};
use citymesh_core::scene::Scene;
use citymesh_core::terrain::{ElevationModel, HgtTile};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;
use std::sync::Arc;

fn hgt_path() -> PathBuf {
    let dir = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    );
    dir.join("dem/N49E008.hgt")
}

fn karlsruhe_model() -> ElevationModel {
    let path = hgt_path();
    let bytes = std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (set CITYMESH_DATA_DIR)", path.display()));
    ElevationModel::new(vec![Arc::new(HgtTile::from_bytes(49, 8, &bytes).unwrap())])
}

/// A box of `km` x `km` centred on Karlsruhe palace.
fn square(km: f64) -> GeoBbox {
    let (lon, lat) = (8.4044, 49.0135);
    let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
    let (dx, dy) = (km * 500.0 / mx, km * 500.0 / my);
    GeoBbox::new(lon - dx, lat - dy, lon + dx, lat + dy).unwrap()
}

fn ground(c: &mut Criterion) {
    let model = karlsruhe_model();
    let bbox = square(2.0);
    c.bench_function("ground_2km_to_glb", |b| {
        b.iter(|| Scene::ground(black_box(&model), black_box(&bbox)).to_glb());
    });
    c.bench_function("ground_2km_mesh_only", |b| {
        b.iter(|| Scene::ground(black_box(&model), black_box(&bbox)));
    });
    // Reading the SRTM file: whole (a server caches it) and only the rows of the box (what
    // `citymesh scene` reads).
    let path = hgt_path();
    let bytes = std::fs::metadata(&path).unwrap().len() as usize;
    c.bench_function("srtm_read_whole", |b| {
        b.iter(|| HgtTile::read(49, 8, std::fs::File::open(&path).unwrap(), bytes).unwrap());
    });
    c.bench_function("srtm_read_band_2km", |b| {
        b.iter(|| {
            let file = std::fs::File::open(&path).unwrap();
            HgtTile::read_band(49, 8, file, bytes, bbox.min_lat(), bbox.max_lat()).unwrap()
        });
    });
}

criterion_group!(benches, ground);
criterion_main!(benches);

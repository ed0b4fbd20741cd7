//! A cold data tile read back into building records: the stored form before issue 40 (Overpass
//! JSON, as `write_overpass_json` writes it) against the packed form (`osm::packed`), for the
//! buildings of Karlsruhe-Kirchfeld. Reads `osm/karlsruhe-kirchfeld.osm.pbf` from
//! `CITYMESH_DATA_DIR` (default `../shared/data`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::osm::{pack, read_buildings, unpack, write_overpass_json};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

// The allocator the server runs with (src/main.rs).
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

fn data_tile(c: &mut Criterion) {
    let buildings = read_buildings(&read("osm/karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let records: Vec<_> = buildings.buildings.iter().collect();
    let json = write_overpass_json(&records);
    let packed = pack(&buildings);
    let n = records.len();
    // Both forms hold the same records: checked once here, so the timings compare like with like.
    assert_eq!(read_buildings(&json).unwrap().buildings.len(), n);
    assert_eq!(unpack(&packed).unwrap().buildings, buildings.buildings);
    eprintln!(
        "kirchfeld data: {n} buildings, JSON {} bytes ({} B per building), packed {} bytes ({} B per building)",
        json.len(),
        json.len() / n,
        packed.len(),
        packed.len() / n
    );
    c.bench_function("data_tile_json_to_records", |b| {
        b.iter(|| read_buildings(black_box(&json)).unwrap());
    });
    c.bench_function("data_tile_packed_to_records", |b| {
        b.iter(|| unpack(black_box(&packed)).unwrap());
    });
    c.bench_function("data_tile_records_to_packed", |b| {
        b.iter(|| pack(black_box(&buildings)));
    });
}

criterion_group!(benches, data_tile);
criterion_main!(benches);

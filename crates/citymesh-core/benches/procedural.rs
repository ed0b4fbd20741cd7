//! A 1 km x 1 km procedural city at complexity 6 (the demo city): generating its definitions, and
//! from the definitions to GLB bytes (clusters, flat ground, buildings, GLB).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::building::set::BuildingSet;
use citymesh_core::procedural::{ProceduralParams, generate_city};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn procedural(c: &mut Criterion) {
    let params = ProceduralParams::default();
    let city = generate_city(&params).unwrap();
    let model = ElevationModel::default();
    let to_glb = |records: Vec<_>| {
        let set = BuildingSet::new(records);
        Scene::new(&model, &city.bbox, &set.groups(), Border::Whole).to_glb()
    };
    let glb = to_glb(city.records.clone());
    eprintln!(
        "procedural city: {} records, GLB {} bytes",
        city.records.len(),
        glb.len()
    );
    c.bench_function("procedural_1km_c6_definitions", |b| {
        b.iter(|| generate_city(black_box(&params)).unwrap());
    });
    c.bench_function("procedural_1km_c6_definitions_to_glb", |b| {
        b.iter(|| to_glb(black_box(city.records.clone())));
    });
}

criterion_group!(benches, procedural);
criterion_main!(benches);

//! Synthetic roof crops for the classifier's training set: one whole sample (scene from real
//! Kirchfeld footprints, render with shadows, sensor effects, crop), as `citymesh render-roofs`
//! makes them.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

#[path = "../tests/common.rs"]
mod common;

use citymesh_core::osm::read_buildings;
use citymesh_core::roof_image::CropRule;
use citymesh_core::roof_image::synthetic::{FootprintPool, Palette, render_sample};
use criterion::{Criterion, criterion_group, criterion_main};

fn render(c: &mut Criterion) {
    let records = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let pool = FootprintPool::from_records(&records.buildings);
    let mut seed = 0u64;
    c.bench_function("roof_sample_render", |b| {
        b.iter(|| {
            seed += 1;
            render_sample(&pool, seed, Palette::Training, CropRule::MODEL).unwrap()
        });
    });
}

criterion_group!(benches, render);
criterion_main!(benches);

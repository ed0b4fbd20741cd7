//! The roof prior's fit on real data (what a cold `roofs=inferred` request pays once per area
//! before the prior is cached): Karlsruhe-Kirchfeld's 2,995 buildings, 572 of them tagged, five
//! cross-validation fits and the final one, and the 2,418 untagged predicted. Reads
//! `osm/karlsruhe-kirchfeld.osm.pbf` from `CITYMESH_DATA_DIR` (default `../shared/data`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::osm::{BuildingRecord, read_buildings};
use citymesh_core::roof_prior::RoofPrior;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::PathBuf;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn kirchfeld() -> Vec<BuildingRecord> {
    let dir = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    );
    let path = dir.join("osm/karlsruhe-kirchfeld.osm.pbf");
    let bytes = std::fs::read(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (set CITYMESH_DATA_DIR)", path.display()));
    read_buildings(&bytes).unwrap().buildings
}

fn fit(c: &mut Criterion) {
    let records = kirchfeld();
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let prior = RoofPrior::fit(&refs);
    eprintln!(
        "kirchfeld prior: {} tagged, {} predicted, cross-validated {:?}",
        prior.report.tagged, prior.report.predicted, prior.report.cross_validated_accuracy
    );
    let mut group = c.benchmark_group("roof_prior");
    group.sample_size(10);
    group.bench_function("kirchfeld_fit_and_predict", |b| {
        b.iter(|| black_box(RoofPrior::fit(black_box(&refs))));
    });
    group.finish();
}

criterion_group!(benches, fit);
criterion_main!(benches);

//! Roof classification with the committed model through ONNX Runtime (the .venv wheel's library,
//! one intra-op thread): a batch of 1 and a batch of 64 crops.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh::roofs::classifier::{MODEL_RULE, Passes, load_classifier};
use citymesh_core::roof_image::synthetic::{FootprintPool, Palette, render_sample};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn classify(c: &mut Criterion) {
    let classifier = load_classifier(None, None, Passes::default())
        .unwrap_or_else(|e| panic!("{e} (scripts/test installs onnxruntime into .venv)"));
    let pool = FootprintPool::procedural(5);
    let crops: Vec<_> = (0..64)
        .map(|i| {
            render_sample(&pool, i, Palette::Training, MODEL_RULE)
                .unwrap()
                .crop
        })
        .collect();
    c.bench_function("classify_batch_1", |b| {
        b.iter(|| classifier.classify(black_box(&crops[..1])).unwrap());
    });
    c.bench_function("classify_batch_64", |b| {
        b.iter(|| classifier.classify(black_box(&crops)).unwrap());
    });
}

criterion_group!(benches, classify);
criterion_main!(benches);

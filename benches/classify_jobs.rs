//! Roof jobs end to end, as a worker runs them: 64 Kirchfeld buildings queued in SQLite, then
//! claimed in rounds of 16, their imagery fetched over HTTP from a local server (256 x 256 noisy
//! PNG tiles, as decoding real imagery costs), stitched, cropped by the crop rule, classified with
//! the committed model (ONNX Runtime from the .venv wheel) and stored. Buildings per second is 64
//! divided by the median.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use axum::http::header;
use citymesh::roofs::classifier::{Passes, load_classifier};
use citymesh::roofs::imagery::{Imagery, ImagerySpec};
use citymesh::roofs::jobs::worker::{WorkerConfig, run_round};
use citymesh::roofs::jobs::{JobQueue, Selection, select_buildings};
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::read_buildings;
use criterion::{Criterion, criterion_group, criterion_main};
use std::time::{Duration, Instant};

const BUILDINGS: usize = 64;

fn noisy_png() -> Vec<u8> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let rgb: Vec<u8> = (0..256 * 256 * 3)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 56) as u8
        })
        .collect();
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &rgb,
        256,
        256,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    png
}

fn jobs(c: &mut Criterion) {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let classifier = load_classifier(None, None, Passes::default())
        .unwrap_or_else(|e| panic!("{e} (scripts/test installs onnxruntime into .venv)"));
    let data = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
        std::path::PathBuf::from,
    );
    let osm = std::fs::read(data.join("osm/karlsruhe-kirchfeld.osm.pbf"))
        .unwrap_or_else(|e| panic!("Kirchfeld OSM data (set CITYMESH_DATA_DIR): {e}"));
    let area: GeoBbox = "8.396,49.052,8.403,49.058".parse().unwrap();
    let mut records = read_buildings(&osm).unwrap().buildings;
    records.retain(|r| {
        let n = &r.outers[0].nodes[0];
        area.contains(n.lon, n.lat)
    });
    let (mut selected, _) = select_buildings(&records, Selection::All);
    selected.truncate(BUILDINGS);
    assert_eq!(selected.len(), BUILDINGS);
    let base = runtime.block_on(async {
        let png = noisy_png();
        let app = axum::Router::new().route(
            "/{z}/{x}/{y}",
            axum::routing::get(move || {
                let png = png.clone();
                async move { ([(header::CONTENT_TYPE, "image/png")], png) }
            }),
        );
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
        format!("http://{addr}")
    });
    let imagery = runtime.block_on(async {
        Imagery::open(ImagerySpec::xyz(
            "bench",
            &format!("{base}/{{z}}/{{x}}/{{y}}"),
        ))
        .await
        .unwrap()
    });
    let mut group = c.benchmark_group("roof_jobs");
    group.sample_size(10);
    group.bench_function("classify_64_buildings_end_to_end", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                total += runtime.block_on(async {
                    let queue = JobQueue::new(&citymesh::db::Database::Sqlite(
                        citymesh::db::open(":memory:").await.unwrap(),
                    ));
                    queue
                        .enqueue(
                            "bench",
                            "bench",
                            classifier.model_id(),
                            &selected,
                            Default::default(),
                        )
                        .await
                        .unwrap();
                    let started = Instant::now();
                    let mut done = 0;
                    while let Some(round) = run_round(
                        &queue,
                        &imagery,
                        &classifier,
                        WorkerConfig::default(),
                        &|_, _, _| {},
                    )
                    .await
                    .unwrap()
                    {
                        done += round.done;
                    }
                    assert_eq!(done, BUILDINGS);
                    started.elapsed()
                });
            }
            total
        });
    });
    group.finish();
}

criterion_group!(benches, jobs);
criterion_main!(benches);

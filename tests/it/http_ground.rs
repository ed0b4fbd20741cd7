//! The ground served over HTTP: real terrain, tiles and their SQLite cache, DEM files in every
//! packaging and state, and the glTF Validator's verdict.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use common::{app_with, assert_valid_glb, dem_dir, get, glb_positions, glb_triangle_count};
use std::io::Write;

#[tokio::test]
async fn scene_has_the_real_terrain_and_passes_the_validator() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let answer = get(&app, "/scene.glb?bbox=8.39,49.04,8.41,49.06").await;
    assert_eq!(answer.status, StatusCode::OK);
    assert_eq!(answer.header("content-type"), "model/gltf-binary");
    assert_eq!(answer.header("x-citymesh-ground"), "dem");
    assert_valid_glb(&answer.body);

    let (positions, origin) = glb_positions(&answer.body);
    assert_eq!(origin["lon"], 8.4);
    assert_eq!(origin["lat"], 49.05);
    assert_eq!(origin["height"], 0.0);
    // The headers give the file's true counts; vertices are shared within planar faces.
    let triangles: usize = answer.header("x-citymesh-triangles").parse().unwrap();
    let vertices: usize = answer.header("x-citymesh-vertices").parse().unwrap();
    assert_eq!(positions.len(), vertices);
    assert_eq!(glb_triangle_count(&answer.body), triangles);
    assert!(
        vertices < 3 * triangles,
        "{vertices} vertices, {triangles} triangles"
    );
    // The raw samples of N49E008 in and around this box span these heights; the mesh, made of
    // samples and averages of them, must stay inside.
    let tile = std::fs::read(dem_dir().join("N49E008.hgt")).unwrap();
    let sample = |lat: f64, lon: f64| {
        let (r, c) = (
            ((50.0 - lat) * 1200.0).round() as usize,
            ((lon - 8.0) * 1200.0).round() as usize,
        );
        i16::from_be_bytes([tile[(r * 1201 + c) * 2], tile[(r * 1201 + c) * 2 + 1]])
    };
    let mut lo = i16::MAX;
    let mut hi = i16::MIN;
    for k in 0..=26 {
        for m in 0..=26 {
            let h = sample(
                49.04 - 1.0 / 1200.0 + f64::from(k) / 1200.0,
                8.39 - 1.0 / 1200.0 + f64::from(m) / 1200.0,
            );
            lo = lo.min(h);
            hi = hi.max(h);
        }
    }
    let (zmin, zmax) = positions
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p[2]), b.max(p[2])));
    assert!(
        zmin >= f64::from(lo) && zmax <= f64::from(hi),
        "mesh {zmin}..{zmax}, samples {lo}..{hi}"
    );
    assert!(
        zmax - zmin > 3.0,
        "real terrain has relief here: {zmin}..{zmax}"
    );
}

#[tokio::test]
async fn tiles_are_cached_in_sqlite_across_restarts() {
    let db = tempfile::tempdir().unwrap();
    let db_file = db.path().join("c.sqlite");
    let uri = "/tiles/16/34297/22492.glb";
    let first = {
        let app = app_with(&dem_dir(), &db_file, &[]).await;
        let a = get(&app, uri).await;
        assert_eq!(a.status, StatusCode::OK);
        assert_eq!(a.header("x-citymesh-cache"), "miss");
        let b = get(&app, uri).await;
        assert_eq!(b.header("x-citymesh-cache"), "hit");
        assert_eq!(a.body, b.body);
        a.body
    };
    // A new server on the same database (once the first one's writes landed, as at its
    // shutdown): served from SQLite, byte for byte.
    common::settle_writes().await;
    let app = app_with(&dem_dir(), &db_file, &[]).await;
    let again = get(&app, uri).await;
    assert_eq!(again.header("x-citymesh-cache"), "sqlite");
    assert_eq!(again.body, first);
    assert_valid_glb(&first);
    // HEAD answers like GET, without a body.
    let head = tower::ServiceExt::oneshot(
        app.clone(),
        axum::http::Request::head(uri)
            .body(axum::body::Body::empty())
            .unwrap(),
    )
    .await
    .unwrap();
    assert_eq!(head.status(), StatusCode::OK);
}

#[tokio::test]
async fn without_dem_files_the_ground_is_flat_and_says_so() {
    let db = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let app = app_with(empty.path(), &db.path().join("c.sqlite"), &[]).await;
    let answer = get(&app, "/scene.glb?bbox=8.39,49.04,8.41,49.06").await;
    assert_eq!(answer.status, StatusCode::OK);
    assert_eq!(
        answer.header("x-citymesh-ground"),
        "flat-fallback; missing=N49E008"
    );
    assert_valid_glb(&answer.body);
    let (positions, _) = glb_positions(&answer.body);
    assert!(!positions.is_empty());
    assert!(positions.iter().all(|p| p[2] == 0.0));
}

/// The GLB of the Karlsruhe scene with `N49E008` stored under `name` with these bytes.
async fn scene_with_file(name: &str, bytes: &[u8]) -> common::Answer {
    let dem = tempfile::tempdir().unwrap();
    std::fs::write(dem.path().join(name), bytes).unwrap();
    let db = tempfile::tempdir().unwrap();
    let app = app_with(dem.path(), &db.path().join("c.sqlite"), &[]).await;
    get(&app, "/scene.glb?bbox=8.39,49.04,8.41,49.06").await
}

#[tokio::test]
async fn gzip_and_zip_files_give_the_same_ground_as_plain_hgt() {
    let raw = std::fs::read(dem_dir().join("N49E008.hgt")).unwrap();
    let plain = scene_with_file("N49E008.hgt", &raw).await;
    assert_eq!(plain.header("x-citymesh-ground"), "dem");

    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(&raw).unwrap();
    let gzipped = scene_with_file("N49E008.hgt.gz", &gz.finish().unwrap()).await;
    assert_eq!(gzipped.header("x-citymesh-ground"), "dem");
    assert_eq!(gzipped.body, plain.body);

    let mut zipped = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    zipped
        .start_file("N49E008.hgt", zip::write::SimpleFileOptions::default())
        .unwrap();
    zipped.write_all(&raw).unwrap();
    let zipped = scene_with_file(
        "N49E008.SRTMGL3.hgt.zip",
        &zipped.finish().unwrap().into_inner(),
    )
    .await;
    assert_eq!(zipped.header("x-citymesh-ground"), "dem");
    assert_eq!(zipped.body, plain.body);
}

#[tokio::test]
async fn broken_hgt_files_count_as_missing_not_as_garbage() {
    let raw = std::fs::read(dem_dir().join("N49E008.hgt")).unwrap();
    // Truncated by one sample, padded by one byte, and a zip with no .hgt inside.
    let truncated = scene_with_file("N49E008.hgt", &raw[..raw.len() - 2]).await;
    let padded = scene_with_file("N49E008.hgt", &[&raw[..], &[0]].concat()).await;
    let mut empty_zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    empty_zip
        .start_file("readme.txt", zip::write::SimpleFileOptions::default())
        .unwrap();
    let no_hgt =
        scene_with_file("N49E008.hgt.zip", &empty_zip.finish().unwrap().into_inner()).await;
    let not_gzip = scene_with_file("N49E008.hgt.gz", b"this is not gzip").await;
    for answer in [truncated, padded, no_hgt, not_gzip] {
        assert_eq!(answer.status, StatusCode::OK);
        assert_eq!(
            answer.header("x-citymesh-ground"),
            "flat-fallback; missing=N49E008"
        );
        let (positions, _) = glb_positions(&answer.body);
        assert!(positions.iter().all(|p| p[2] == 0.0));
    }
}

#[tokio::test]
async fn served_openapi_matches_the_committed_file() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let served = get(&app, "/openapi.json").await;
    assert_eq!(served.status, StatusCode::OK);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("openapi/openapi.json");
    let committed: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(
        served.json(),
        committed,
        "openapi/openapi.json is out of date: regenerate it with `cargo run --release -- openapi > openapi/openapi.json`"
    );
    let docs = get(&app, "/docs/").await;
    assert_eq!(docs.status, StatusCode::OK);
    assert!(String::from_utf8_lossy(&docs.body).contains("swagger"));
}

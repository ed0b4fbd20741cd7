//! Helpers for the end-to-end tests: real data paths, an app over a temporary database, requests
//! through the router, and the Khronos glTF Validator.
#![allow(dead_code)]

pub mod decode;
pub mod imagery;
pub mod postgres;

use axum::body::Body;
use axum::http::{HeaderMap, Request, StatusCode};
use citymesh::cli::ServeArgs;
use clap::Parser;
use http_body_util::BodyExt;
use std::path::{Path, PathBuf};
use tower::ServiceExt;

/// The real data folder: `CITYMESH_DATA_DIR`, else `../shared/data` beside the project.
pub fn data_dir() -> PathBuf {
    let dir = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
        PathBuf::from,
    );
    assert!(
        dir.join("dem").is_dir(),
        "real test data not found at {} (set CITYMESH_DATA_DIR to the folder holding dem/ and osm/)",
        dir.display()
    );
    dir
}

/// The bytes of a file in `osm/`, unzipped when it ends in `.gz`.
pub fn osm_bytes(name: &str) -> Vec<u8> {
    use std::io::Read;
    let path = data_dir().join("osm").join(name);
    let raw =
        std::fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    if !name.ends_with(".gz") {
        return raw;
    }
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(&raw[..])
        .read_to_end(&mut out)
        .unwrap();
    out
}

pub fn dem_dir() -> PathBuf {
    data_dir().join("dem")
}

/// A running app over `dem` with a fresh database in `db_dir`.
pub async fn app_with(dem: &Path, db: &Path, extra: &[&str]) -> axum::Router {
    app_with_clock(dem, db, extra, citymesh::clock::Clock::system()).await
}

/// [`app_with`], its stores' rows stamped by `clock` (a manual one the test moves).
pub async fn app_with_clock(
    dem: &Path,
    db: &Path,
    extra: &[&str],
    clock: citymesh::clock::Clock,
) -> axum::Router {
    let mut argv = vec![
        "serve",
        "--dem-dir",
        dem.to_str().unwrap(),
        "--cache-db",
        db.to_str().unwrap(),
    ];
    // Tests never reach the internet: without local OSM files or a stub upstream, no upstream.
    if !extra
        .iter()
        .any(|a| *a == "--osm" || *a == "--overpass-url" || *a == "--offline")
    {
        argv.push("--offline");
    }
    argv.extend_from_slice(extra);
    let args = ServeArgs::parse_from(argv);
    app_of(
        citymesh::server::build_state_with_clock(&args, clock)
            .await
            .unwrap(),
    )
}

/// The state of a server of Karlsruhe-Kirchfeld from its PBF file, over a database in `db`
/// (for tests that wait on its world summaries: [`world_ready`]).
pub async fn kirchfeld_state(db: &tempfile::TempDir) -> citymesh::state::AppState {
    let file = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let args = ServeArgs::parse_from([
        "serve",
        "--dem-dir",
        dem_dir().to_str().unwrap(),
        "--cache-db",
        db.path().join("c.sqlite").to_str().unwrap(),
        "--osm",
        file.to_str().unwrap(),
    ]);
    citymesh::server::build_state(&args).await.unwrap()
}

/// The app of a state, its tile cache known to [`settle_writes`].
pub fn app_of(state: citymesh::state::AppState) -> axum::Router {
    if let Ok(mut caches) = CACHES.lock() {
        caches.push(state.tiles.clone());
    }
    citymesh::app(state)
}

/// An app serving Karlsruhe-Kirchfeld from its PBF file, over a database in `db`.
pub async fn kirchfeld_app(db: &tempfile::TempDir) -> axum::Router {
    let file = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    app_with(
        &dem_dir(),
        &db.path().join("c.sqlite"),
        &["--osm", file.to_str().unwrap()],
    )
    .await
}

/// The tile caches of the apps this test binary made.
static CACHES: std::sync::Mutex<Vec<std::sync::Arc<citymesh::cache::TileCache>>> =
    std::sync::Mutex::new(Vec::new());

/// Waits until every generated tile of the apps made so far is written to SQLite (tiles are
/// written after their response), as a server does at shutdown: call it before opening the same
/// database again.
pub async fn settle_writes() {
    let caches: Vec<_> = CACHES.lock().map(|c| c.clone()).unwrap_or_default();
    for c in caches {
        c.flush().await;
    }
}

pub struct Answer {
    pub status: StatusCode,
    pub headers: HeaderMap,
    pub body: Vec<u8>,
}

impl Answer {
    /// The body as text (lossy).
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }

    pub fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "body is not JSON ({e}): {}",
                String::from_utf8_lossy(&self.body)
            )
        })
    }
    pub fn header(&self, name: &str) -> &str {
        self.headers
            .get(name)
            .unwrap_or_else(|| panic!("no {name} header"))
            .to_str()
            .unwrap()
    }
}

/// Sends a request through the router.
pub async fn send(app: &axum::Router, request: Request<Body>) -> Answer {
    let response = app.clone().oneshot(request).await.unwrap();
    let status = response.status();
    let headers = response.headers().clone();
    let body = response.into_body().collect().await.unwrap().to_bytes();
    Answer {
        status,
        headers,
        body: body.to_vec(),
    }
}

/// POSTs JSON.
pub async fn post_json(app: &axum::Router, uri: &str, body: serde_json::Value) -> Answer {
    let request = Request::post(uri)
        .header("content-type", "application/json")
        .body(Body::from(body.to_string()))
        .unwrap();
    send(app, request).await
}

pub async fn get(app: &axum::Router, uri: &str) -> Answer {
    let response = app
        .clone()
        .oneshot(Request::get(uri).body(Body::empty()).unwrap())
        .await
        .unwrap();
    let status = response.status();
    let headers = response.headers().clone();
    let body = response
        .into_body()
        .collect()
        .await
        .unwrap()
        .to_bytes()
        .to_vec();
    Answer {
        status,
        headers,
        body,
    }
}

/// Runs the Khronos glTF Validator on GLB bytes and returns its summary
/// `{"errors", "warnings", "infos", "hints", "messages"}`.
pub fn validate_glb(glb: &[u8]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("t.glb");
    std::fs::write(&file, glb).unwrap();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = std::process::Command::new("node")
        .arg(root.join("scripts/validate-glb.mjs"))
        .arg(&file)
        .current_dir(&root)
        .output()
        .expect("node must be installed to run the glTF Validator (scripts/test checks this)");
    assert!(
        out.status.code() != Some(2),
        "gltf-validator is not installed: run scripts/test, which runs `npm ci`\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(line.trim()).unwrap_or_else(|e| panic!("validator output ({e}): {line}"))
}

/// Asserts the validator finds no errors and no warnings.
pub fn assert_valid_glb(glb: &[u8]) {
    let report = validate_glb(glb);
    assert_eq!(report["errors"], 0, "{report}");
    assert_eq!(report["warnings"], 0, "{report}");
}

/// Triangles of a GLB: its indices over three, over every primitive.
pub fn glb_triangle_count(glb: &[u8]) -> usize {
    let gltf = gltf::Gltf::from_slice(glb).expect("a GLB the gltf crate reads");
    let blob = gltf.blob.as_deref().unwrap_or_default();
    gltf.meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
        .map(|p| {
            let reader = p.reader(|_| Some(blob));
            reader.read_indices().map_or(0, |i| i.into_u32().count()) / 3
        })
        .sum()
}

/// Decoded positions of a GLB in the local frame `[east, north, up]`, and its origin.
pub fn glb_positions(glb: &[u8]) -> (Vec<[f64; 3]>, serde_json::Value) {
    let gltf = gltf::Gltf::from_slice(glb).expect("a GLB the gltf crate reads");
    let scene = gltf.default_scene().unwrap();
    let extras: serde_json::Value =
        serde_json::from_str(scene.extras().as_ref().unwrap().get()).unwrap();
    let mut out = Vec::new();
    if let Some(blob) = gltf.blob.as_deref() {
        for mesh in gltf.meshes() {
            for prim in mesh.primitives() {
                let reader = prim.reader(|_| Some(blob));
                for [x, y, z] in reader.read_positions().unwrap() {
                    out.push([f64::from(x), -f64::from(z), f64::from(y)]);
                }
            }
        }
    }
    (out, extras["origin"].clone())
}

/// The log lines of a server started by [`serve_binary`].
pub type ServerLog = std::io::Lines<std::io::BufReader<std::process::ChildStdout>>;

/// Starts the real binary (`citymesh serve --offline` on a free port, real DEM files, a database
/// in `db`, then `extra`); answers it, its address and the rest of its log.
pub fn serve_binary(db: &Path, extra: &[&str]) -> (std::process::Child, String, ServerLog) {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .args(["serve", "--offline", "--listen", "127.0.0.1:0", "--dem-dir"])
        .arg(dem_dir())
        .arg("--cache-db")
        .arg(db.join("c.sqlite"))
        .args(extra)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = std::io::BufReader::new(child.stdout.take().unwrap()).lines();
    let addr = loop {
        let line = lines
            .next()
            .expect("server exited before listening")
            .unwrap();
        if let Some(rest) = line.split("listening on http://").nth(1) {
            break rest.split('/').next().unwrap().to_owned();
        }
    };
    (child, addr, lines)
}

/// Waits until the server's world tileset is summarised (made in the background when a server
/// starts), on the summaries' own readiness, and answers its progress. A minute without it
/// fails the test.
pub async fn world_ready(state: &citymesh::state::AppState) -> citymesh::cache::SummaryProgress {
    tokio::time::timeout(std::time::Duration::from_secs(60), state.summaries.ready())
        .await
        .expect("the world tileset was never summarised");
    state.summaries.progress()
}

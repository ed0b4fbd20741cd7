//! Hostile requests and faulty upstreams: one test per defect class an outside attack found.
//! Each answers a 4xx (our input) or 502/503/504 (upstream) with the JSON error body, costs a
//! bounded amount, and never panics. Long-running cases are bounded by the server's own limits.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use common::{app_with, dem_dir, get, osm_bytes, serve_binary};
use http_body_util::BodyExt;
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;
use tower::ServiceExt;

async fn demo_app(db: &tempfile::TempDir, extra: &[&str]) -> axum::Router {
    let empty = db.path().join("no-dem");
    std::fs::create_dir_all(&empty).unwrap();
    let mut args = Vec::new();
    if !extra.contains(&"--assets-dir") {
        args.extend(["--assets-dir", "/nonexistent"]);
    }
    args.extend_from_slice(extra);
    // No data at all: the demo city, not --offline (app_with adds it unless told otherwise).
    let argv: Vec<String> = ["serve", "--dem-dir", empty.to_str().unwrap(), "--cache-db"]
        .iter()
        .map(|s| (*s).to_owned())
        .chain([db.path().join("c.sqlite").display().to_string()])
        .chain(args.iter().map(|s| (*s).to_owned()))
        .collect();
    use clap::Parser;
    let parsed = citymesh::cli::ServeArgs::parse_from(argv);
    common::app_of(citymesh::server::build_state(&parsed).await.unwrap())
}

async fn send(
    app: &axum::Router,
    request: Request<Body>,
) -> (StatusCode, axum::http::HeaderMap, Value) {
    let response = app.clone().oneshot(request).await.unwrap();
    let (status, headers) = (response.status(), response.headers().clone());
    let body = response.into_body().collect().await.unwrap().to_bytes();
    let json = serde_json::from_slice(&body).unwrap_or_else(|e| {
        panic!(
            "{status}: body is not JSON ({e}): {}",
            String::from_utf8_lossy(&body)
        )
    });
    (status, headers, json)
}

/// Status, headers and body of a stub answer.
type Answer = (u16, Vec<(String, String)>, Vec<u8>);

/// A counting stub upstream whose answer the test chooses.
struct Upstream {
    requests: AtomicUsize,
    answer: std::sync::Mutex<Answer>,
}

async fn start_upstream(
    status: u16,
    headers: &[(&str, &str)],
    body: Vec<u8>,
) -> (Arc<Upstream>, String) {
    let up = Arc::new(Upstream {
        requests: AtomicUsize::new(0),
        answer: std::sync::Mutex::new((
            status,
            headers
                .iter()
                .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                .collect(),
            body,
        )),
    });
    async fn handler(
        axum::extract::State(up): axum::extract::State<Arc<Upstream>>,
    ) -> axum::response::Response {
        up.requests.fetch_add(1, Ordering::SeqCst);
        let (status, headers, body) = up.answer.lock().unwrap().clone();
        let mut r = axum::response::Response::new(Body::from(body));
        *r.status_mut() = StatusCode::from_u16(status).unwrap();
        for (k, v) in headers {
            r.headers_mut().insert(
                axum::http::HeaderName::from_bytes(k.as_bytes()).unwrap(),
                v.parse().unwrap(),
            );
        }
        r
    }
    let app = axum::Router::new()
        .route("/api/interpreter", axum::routing::post(handler))
        .with_state(up.clone());
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    // A key in the URL, which error messages must never repeat.
    (up, format!("http://{addr}/api/interpreter?key=s3cret-key"))
}

async fn online(db: &tempfile::TempDir, url: &str, extra: &[&str]) -> axum::Router {
    let mut args = vec!["--overpass-url", url, "--overpass-timeout-s", "5"];
    if !extra.contains(&"--overpass-retries") {
        args.extend(["--overpass-retries", "0"]);
    }
    args.extend_from_slice(extra);
    app_with(&dem_dir(), &db.path().join("c.sqlite"), &args).await
}

/// `POST /scene.glb` with a GeoJSON body.
fn post_scene(geojson: Value) -> Request<Body> {
    Request::post("/scene.glb")
        .header("content-type", "application/geo+json")
        .body(Body::from(geojson.to_string()))
        .unwrap()
}

const KIRCHFELD_TILE: &str = "/tiles/16/34297/22493.glb";

#[tokio::test]
async fn d1_thin_and_long_boxes_are_refused_before_any_work() {
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(200, &[], br#"{"elements": []}"#.to_vec()).await;
    let app = online(&db, &url, &[]).await;
    // 22 km² but 1.3 million ground cells.
    for path in ["/scene.glb", "/scene/stats", "/scene"] {
        let a = get(&app, &format!("{path}?bbox=-180,0,180,0.000005")).await;
        assert_eq!(a.status, StatusCode::BAD_REQUEST, "{path}");
        assert_eq!(a.json()["error"], "bbox_too_large");
        assert!(
            a.json()["detail"]
                .as_str()
                .unwrap()
                .contains("ground cells")
        );
    }
    // 1.6 km² and few cells, but 46 data tiles long: refused before any upstream call.
    let long = get(&app, "/scene/stats?bbox=8.0,49.0,9.0,49.0002").await;
    assert_eq!(
        long.status,
        StatusCode::BAD_REQUEST,
        "{}",
        String::from_utf8_lossy(&long.body)
    );
    assert!(
        long.json()["detail"]
            .as_str()
            .unwrap()
            .contains("data tiles"),
        "{}",
        long.json()
    );
    assert_eq!(up.requests.load(Ordering::SeqCst), 0);
}

#[tokio::test]
async fn d1_offline_headers_stay_short() {
    let db = tempfile::tempdir().unwrap();
    // Offline with nothing stored: every data tile is missing; the header lists eight at most.
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &["--offline"]).await;
    let a = get(&app, "/scene.glb?bbox=8.30,49.00,8.42,49.02").await;
    assert_eq!(a.status, StatusCode::OK);
    let osm = a.header("x-citymesh-osm");
    assert!(osm.len() < 200, "{osm}");
    assert!(osm.contains("more)"), "{osm}");
}

#[tokio::test]
async fn d2_huge_and_crossing_rings_are_refused() {
    let db = tempfile::tempdir().unwrap();
    let app = demo_app(&db, &[]).await;
    let ring = |n: usize, zigzag: bool| -> Vec<[f64; 2]> {
        let mut r: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                let radius = if zigzag && i % 2 == 1 { 0.0002 } else { 0.0008 };
                [8.4 + radius * t.cos() * 1.5, 49.0 + radius * t.sin()]
            })
            .collect();
        if zigzag {
            // Swap two far vertices: the ring crosses itself.
            r.swap(10, n / 2);
        }
        r.push(r[0]);
        r
    };
    let feature = |r: Vec<[f64; 2]>| {
        json!({"type": "FeatureCollection", "features": [{"type": "Feature",
            "properties": {"building": "yes", "height": 10},
            "geometry": {"type": "Polygon", "coordinates": [r]}}]})
    };
    // 30,000 vertices: over the cap per ring, refused without the quadratic check.
    let (status, _, body) = send(&app, post_scene(feature(ring(30_000, false)))).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");
    assert!(
        body["detail"].as_str().unwrap().contains("4000 vertices"),
        "{body}"
    );
    // 3,000 vertices crossing itself: found by the sweep.
    let (status, _, body) = send(&app, post_scene(feature(ring(3_000, true)))).await;
    assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY, "{body}");
    assert!(
        body["detail"].as_str().unwrap().contains("crosses itself"),
        "{body}"
    );
    // The same ring without the swap is a valid building.
    let ok = app
        .clone()
        .oneshot(post_scene(feature(ring(3_000, false))))
        .await
        .unwrap();
    assert_eq!(ok.status(), StatusCode::OK);
}

#[tokio::test]
async fn d4_oversized_and_incomplete_upstream_answers_are_502_and_not_stored() {
    // 2 MB of valid JSON against a 1 MB limit.
    let mut big = br#"{"elements": [], "padding": ""#.to_vec();
    big.extend(std::iter::repeat_n(b'x', 2 << 20));
    big.extend_from_slice(br#""}"#);
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(200, &[], big).await;
    let app = online(&db, &url, &["--overpass-max-mb", "1"]).await;
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::BAD_GATEWAY);
    assert!(
        a.json()["detail"]
            .as_str()
            .unwrap()
            .contains("more than 1 MB"),
        "{}",
        a.json()
    );
    assert!(!a.json()["detail"].as_str().unwrap().contains("s3cret"));
    // Nothing was stored: the next request asks again.
    assert_eq!(
        get(&app, KIRCHFELD_TILE).await.status,
        StatusCode::BAD_GATEWAY
    );
    assert_eq!(up.requests.load(Ordering::SeqCst), 2);

    // A relation naming a way the answer lacks: incomplete.
    let cut = json!({"elements": [
        {"type": "relation", "id": 1, "tags": {"building": "yes", "type": "multipolygon"},
         "members": [{"type": "way", "ref": 2, "role": "outer"}]}]});
    *up.answer.lock().unwrap() = (200, vec![], cut.to_string().into_bytes());
    let db2 = tempfile::tempdir().unwrap();
    let app = online(&db2, &url, &[]).await;
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::BAD_GATEWAY);
    assert!(
        a.json()["detail"].as_str().unwrap().contains("names way 2"),
        "{}",
        a.json()
    );
}

#[tokio::test]
async fn upstream_errors_name_no_url_cap_retry_after_and_tell_504s_apart() {
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(500, &[], b"boom".to_vec()).await;
    let app = online(&db, &url, &[]).await;
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::BAD_GATEWAY);
    let detail = a.json()["detail"].as_str().unwrap().to_owned();
    assert!(detail.contains("the OpenStreetMap upstream"), "{detail}");
    assert!(
        !detail.contains("s3cret") && !detail.contains("127.0.0.1"),
        "{detail}"
    );

    *up.answer.lock().unwrap() = (504, vec![], b"gateway timeout".to_vec());
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::GATEWAY_TIMEOUT);
    let detail = a.json()["detail"].as_str().unwrap().to_owned();
    assert!(detail.contains("reported a gateway timeout"), "{detail}");
    assert!(!detail.contains("did not answer within"), "{detail}");

    *up.answer.lock().unwrap() = (429, vec![("retry-after".into(), "100000".into())], vec![]);
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(a.header("retry-after"), "120");
}

#[tokio::test]
async fn d9_after_a_429_no_request_calls_upstream_until_its_delay_has_passed() {
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(429, &[("retry-after", "30")], vec![]).await;
    // Retries allowed: a 429 is still asked once.
    let app = online(&db, &url, &["--overpass-retries", "2"]).await;
    let a = get(&app, KIRCHFELD_TILE).await;
    assert_eq!(a.status, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(a.json()["error"], "upstream_busy");
    let after_first = up.requests.load(Ordering::SeqCst);
    assert_eq!(after_first, 1, "a 429 was retried within the request");
    // Other places, other requests: answered at once, without a call.
    for tile in ["/tiles/16/34290/22490.glb", "/tiles/16/34280/22480.glb"] {
        let b = get(&app, tile).await;
        assert_eq!(b.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(b.json()["error"], "upstream_held_back");
        let wait: u64 = b.header("retry-after").parse().unwrap();
        assert!((1..=30).contains(&wait), "{wait}");
        assert!(b.json()["detail"].as_str().unwrap().contains("429"));
    }
    assert_eq!(up.requests.load(Ordering::SeqCst), after_first);
}

#[tokio::test]
async fn d10_overpass_calls_are_bounded_per_request_and_per_minute() {
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(200, &[], dense_city(3)).await;
    let app = online(&db, &url, &["--overpass-calls-per-request", "4"]).await;
    // A zoom-12 tile needs more than 4 data tiles: each request fetches 4 more (and keeps them)
    // and says so, until the last one has what it needs.
    let tile = "/tiles/12/2143/1405.glb";
    let mut calls = 0;
    let mut asked = 0;
    loop {
        let a = get(&app, tile).await;
        asked += 1;
        let now = up.requests.load(Ordering::SeqCst);
        assert!(now - calls <= 4, "one request made {} calls", now - calls);
        calls = now;
        if a.status == StatusCode::OK {
            break;
        }
        assert_eq!(a.status, StatusCode::SERVICE_UNAVAILABLE, "{}", a.text());
        assert_eq!(a.json()["error"], "upstream_budget");
        assert_eq!(a.header("retry-after"), "1");
        assert_eq!(now, 4 * asked);
        assert!(asked < 20);
    }
    assert!(asked >= 3, "{asked} requests, {calls} calls");

    // Three calls a minute for all requests together: the fourth is held back, and so is the
    // next request's first.
    let db = tempfile::tempdir().unwrap();
    let (up, url) = start_upstream(200, &[], dense_city(3)).await;
    let app = online(&db, &url, &["--overpass-calls-per-minute", "3"]).await;
    let a = get(&app, tile).await;
    assert_eq!(a.status, StatusCode::SERVICE_UNAVAILABLE, "{}", a.text());
    assert_eq!(a.json()["error"], "upstream_held_back");
    assert!(
        a.json()["detail"]
            .as_str()
            .unwrap()
            .contains("--overpass-calls-per-minute")
    );
    let wait: u64 = a.header("retry-after").parse().unwrap();
    assert!((1..=60).contains(&wait), "{wait}");
    assert_eq!(up.requests.load(Ordering::SeqCst), 3);
    let b = get(&app, "/tiles/12/2150/1410.glb").await;
    assert_eq!(b.status, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(up.requests.load(Ordering::SeqCst), 3);
}

#[tokio::test]
async fn d5_overflowing_weights_are_refused_not_a_panic() {
    let db = tempfile::tempdir().unwrap();
    let app = demo_app(&db, &[]).await;
    for query in [
        "layouts=detached:1e308,row:1e308",
        "roofs=flat:1e308,gabled:1e308",
        "seed=9223372036854775808",
    ] {
        for path in ["/procedural.glb", "/procedural.geojson"] {
            let a = get(&app, &format!("{path}?{query}")).await;
            assert_eq!(a.status, StatusCode::BAD_REQUEST, "{path}?{query}");
            let code = a.json()["error"].as_str().unwrap().to_owned();
            assert!(
                code == "invalid_parameter" || code == "invalid_query",
                "{path}?{query}: {code}"
            );
        }
    }
}

/// Bytes and count of the stored generated tiles.
async fn stored_tiles(db: &std::path::Path) -> (i64, i64) {
    let pool = citymesh::db::open(db.to_str().unwrap()).await.unwrap();
    let row: (i64, i64) =
        sqlx::query_as("SELECT COALESCE(SUM(length(bytes)), 0), COUNT(*) FROM generated_tiles")
            .fetch_one(&pool)
            .await
            .unwrap();
    row
}

#[tokio::test]
async fn d6_the_tile_store_stays_under_its_bound_evicting_least_recently_used() {
    let db = tempfile::tempdir().unwrap();
    // No memory cache, so every repeat comes from SQLite (or is generated again if evicted).
    let app = demo_app(
        &db,
        &[
            "--tile-store-mb",
            "1",
            "--memory-mb",
            "0",
            "--max-zoom",
            "18",
        ],
    )
    .await;
    // Distinct z18 tiles over the demo city (around 8.4044 E, 49.0135 N), newest last.
    let first = "/tiles/18/137188/90010.glb";
    assert_eq!(get(&app, first).await.status, StatusCode::OK);
    // Rows are written just after their answers: wait for them, as a later request would.
    common::settle_writes().await;
    let mut total = 0usize;
    let mut k = 0;
    while total < 3 << 20 {
        let (x, y) = (137_180 + k % 16, 90_000 + k / 16);
        let a = get(&app, &format!("/tiles/18/{x}/{y}.glb")).await;
        assert_eq!(a.status, StatusCode::OK);
        common::settle_writes().await;
        total += a.body.len();
        k += 1;
        // Keep one tile in use: it must survive eviction.
        assert_ne!(
            get(&app, first).await.header("x-citymesh-cache"),
            "miss",
            "after {k} tiles"
        );
    }
    let (bytes, count) = stored_tiles(&db.path().join("c.sqlite")).await;
    assert!(bytes <= 1 << 20, "{bytes} bytes stored");
    assert!(count < k, "{count} of {k} tiles stored");
    // The least recently used tile was evicted: asking again generates it.
    assert_eq!(
        get(&app, "/tiles/18/137180/90000.glb")
            .await
            .header("x-citymesh-cache"),
        "miss"
    );
}

#[tokio::test]
async fn every_error_has_a_json_body_and_media_types_ignore_case() {
    let db = tempfile::tempdir().unwrap();
    let app = demo_app(&db, &[]).await;
    // 405: a method the route does not answer.
    let (status, headers, body) = send(
        &app,
        Request::post("/tiles/16/1/1.glb")
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::METHOD_NOT_ALLOWED);
    assert_eq!(body["error"], "method_not_allowed");
    assert!(headers.get("allow").is_some());
    // A missing static file.
    let (status, _, body) = send(
        &app,
        Request::get("/vendor/three/nope.js")
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(
        (status, body["error"].as_str()),
        (StatusCode::NOT_FOUND, Some("not_found"))
    );
    // 414 and 431.
    let long = format!("/scene.glb?bbox={}", "1".repeat(9000));
    let (status, _, body) = send(&app, Request::get(long).body(Body::empty()).unwrap()).await;
    assert_eq!(
        (status, body["error"].as_str()),
        (StatusCode::URI_TOO_LONG, Some("uri_too_long"))
    );
    let mut big = Request::get("/health");
    for i in 0..40 {
        big = big.header(format!("x-filler-{i}"), "v".repeat(1000));
    }
    let (status, _, body) = send(&app, big.body(Body::empty()).unwrap()).await;
    assert_eq!(
        (status, body["error"].as_str()),
        (
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            Some("headers_too_large")
        )
    );
    // Media types are case-insensitive.
    let geojson = json!({"type": "FeatureCollection", "features": [{"type": "Feature",
        "properties": {"building": "yes", "height": 10},
        "geometry": {"type": "Polygon", "coordinates": [[[8.4, 49.0], [8.4003, 49.0], [8.4003, 49.0002], [8.4, 49.0002], [8.4, 49.0]]]}}]});
    let r = app
        .clone()
        .oneshot(
            Request::post("/scene.glb")
                .header("content-type", "APPLICATION/JSON; charset=UTF-8")
                .body(Body::from(geojson.to_string()))
                .unwrap(),
        )
        .await
        .unwrap();
    assert_eq!(r.status(), StatusCode::OK);
}

/// Round 3, item 6: `/vendor` serves a package's own files, never what a link inside it points
/// to; an unsatisfiable range gets a 416 whose body says what to fix.
#[tokio::test]
async fn vendor_files_stay_inside_their_package_and_a_416_says_why() {
    let db = tempfile::tempdir().unwrap();
    let assets = db.path().join("assets");
    let three = assets.join("three");
    std::fs::create_dir_all(&three).unwrap();
    std::fs::write(
        three.join("three.module.js"),
        "export const REVISION = '1';",
    )
    .unwrap();
    let secret = db.path().join("secret.txt");
    std::fs::write(&secret, "not for clients").unwrap();
    std::os::unix::fs::symlink(&secret, three.join("leak.js")).unwrap();
    std::os::unix::fs::symlink(db.path(), three.join("up")).unwrap();
    let app = demo_app(&db, &["--assets-dir", assets.to_str().unwrap()]).await;
    let ok = common::get(&app, "/vendor/three/three.module.js").await;
    assert_eq!(ok.status, StatusCode::OK);
    assert_eq!(ok.text(), "export const REVISION = '1';");
    for path in [
        "/vendor/three/leak.js",
        "/vendor/three/up/secret.txt",
        "/vendor/three/up/c.sqlite",
    ] {
        let (status, _, body) = send(&app, Request::get(path).body(Body::empty()).unwrap()).await;
        assert_eq!(
            (status, body["error"].as_str()),
            (StatusCode::NOT_FOUND, Some("not_found")),
            "{path}"
        );
    }
    let (status, headers, body) = send(
        &app,
        Request::get("/vendor/three/three.module.js")
            .header("range", "bytes=1000-2000")
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(status, StatusCode::RANGE_NOT_SATISFIABLE);
    assert_eq!(body["error"], "range_not_satisfiable");
    assert_eq!(headers["content-range"], "bytes */28");
}

#[tokio::test]
async fn load_time_skips_are_reported_by_id_and_missing_courtyards_repaired() {
    // Kirchfeld as Overpass JSON without one node of way 35538135 and without the courtyard
    // way of relation 1776559.
    let mut doc: Value =
        serde_json::from_slice(&osm_bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
    let elements = doc["elements"].as_array_mut().unwrap();
    let way = elements
        .iter()
        .find(|e| e["type"] == "way" && e["id"] == 35_538_135)
        .unwrap()
        .clone();
    let node = way["nodes"][0].as_i64().unwrap();
    elements.retain(|e| {
        let dropped_node = e["type"] == "node" && e["id"] == node;
        let dropped_way = e["type"] == "way" && e["id"] == 132_344_585;
        !(dropped_node || dropped_way)
    });
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("cut.json");
    std::fs::write(&file, serde_json::to_vec(&doc).unwrap()).unwrap();
    let app = app_with(
        &dem_dir(),
        &db.path().join("c.sqlite"),
        &["--osm", file.to_str().unwrap()],
    )
    .await;
    let stats = get(&app, "/scene/stats?bbox=8.3877,49.0390,8.4039,49.0640")
        .await
        .json();
    let b = &stats["buildings"];
    let skipped: Vec<String> = b["skipped_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| {
            format!(
                "{} {}",
                s["id"].as_str().unwrap(),
                s["reason"].as_str().unwrap()
            )
        })
        .collect();
    assert!(
        skipped.contains(&"way/35538135 missing_nodes".to_owned()),
        "{skipped:?}"
    );
    assert!(b["skipped"]["missing_nodes"].as_u64().unwrap() >= 1);
    assert_eq!(
        b["repaired_ids"],
        // Its office drawn over the rest of it, then its missing courtyard.
        json!([{"id": "relation/1776559", "what": "overlap_cut_out"},
               {"id": "relation/1776559", "what": "missing_inner_ring"}])
    );
    // `citymesh scene` on the same file and box reports the same, in its --stats file and,
    // briefly, on the console.
    let (glb, figures) = (db.path().join("cut.glb"), db.path().join("cut-stats.json"));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .args(["scene", "--osm", file.to_str().unwrap(), "--dem-dir"])
        .arg(dem_dir())
        .args(["--bbox", "8.3877,49.0390,8.4039,49.0640", "-o"])
        .arg(&glb)
        .arg("--stats")
        .arg(&figures)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cli: Value = serde_json::from_slice(&std::fs::read(&figures).unwrap()).unwrap();
    for key in [
        "skipped",
        "skipped_ids",
        "repaired_ids",
        "roof_shape_unsupported_ids",
        "area_lost_ids",
        "generated",
    ] {
        assert_eq!(cli["buildings"][key], b[key], "{key}");
    }
    let console = String::from_utf8_lossy(&out.stderr);
    assert!(
        console.contains("way/35538135 (missing_nodes)")
            && console.contains("relation/1776559 (missing_inner_ring)"),
        "{console}"
    );
    // A box elsewhere does not report them.
    let far = get(&app, "/scene/stats?bbox=8.40,49.00,8.41,49.01")
        .await
        .json();
    assert_eq!(far["buildings"]["skipped_ids"], json!([]));
}

#[tokio::test]
async fn start_up_says_what_to_fix_about_the_cache_database() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let db = file.join("c.sqlite");
    use clap::Parser;
    let args = citymesh::cli::ServeArgs::parse_from([
        "serve",
        "--offline",
        "--cache-db",
        db.to_str().unwrap(),
    ]);
    let e = format!(
        "{:#}",
        citymesh::server::build_state(&args).await.err().unwrap()
    );
    assert!(e.contains("is a file") && e.contains("--cache-db"), "{e}");
}

/// Whether the server closes the connection before `bound` (reads return end of file or reset).
fn closed_by_server(mut stream: TcpStream, bound: Duration) -> bool {
    stream.set_read_timeout(Some(bound)).unwrap();
    let mut buf = [0u8; 1024];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => {}
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.kind() == std::io::ErrorKind::TimedOut =>
            {
                return false;
            }
            Err(_) => return true,
        }
    }
}

#[test]
fn d3_half_sent_headers_idle_connections_and_the_connection_cap() {
    let db = tempfile::tempdir().unwrap();
    let (mut child, addr, log) = serve_binary(
        db.path(),
        &[
            "--header-timeout-s",
            "1",
            "--idle-timeout-s",
            "3",
            "--request-timeout-s",
            "2",
            "--max-connections",
            "2",
            "--reserved-connections",
            "0",
        ],
    );
    // Keep reading the log so the server never blocks on a full pipe.
    std::thread::spawn(move || log.for_each(drop));
    // A half-sent request header is dropped after the header timeout.
    let mut half = TcpStream::connect(&addr).unwrap();
    half.write_all(b"GET /health HTTP/1.1\r\nHost: x\r\n")
        .unwrap();
    assert!(
        closed_by_server(half, Duration::from_secs(10)),
        "half-sent header held open"
    );
    // An idle keep-alive connection is closed after the idle timeout.
    let mut idle = TcpStream::connect(&addr).unwrap();
    idle.write_all(b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    assert!(
        closed_by_server(idle, Duration::from_secs(15)),
        "idle connection held open"
    );
    // With two connections open, a third is not served until one closes.
    let a = TcpStream::connect(&addr).unwrap();
    let b = TcpStream::connect(&addr).unwrap();
    // The server accepts in arrival order, one client waiting for a slot at a time: A and B
    // have the slots before C is accepted.
    let mut c = TcpStream::connect(&addr).unwrap();
    c.write_all(b"GET /health HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
        .unwrap();
    c.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let mut buf = [0u8; 64];
    assert!(
        c.read(&mut buf).is_err(),
        "a third connection was served over the cap"
    );
    drop((a, b));
    c.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut answer = Vec::new();
    c.read_to_end(&mut answer).unwrap();
    assert!(
        answer.starts_with(b"HTTP/1.1 200"),
        "{}",
        String::from_utf8_lossy(&answer)
    );
    child.kill().unwrap();
    child.wait().unwrap();
}

/// Asks `/metrics` on the keep-alive connection `stream`; answers the connections open on
/// general and on reserved slots.
fn connections_open(stream: &mut TcpStream) -> (u64, u64) {
    stream
        .write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    let mut answer = Vec::new();
    let mut buf = [0u8; 8192];
    let (head_end, length) = loop {
        let n = stream.read(&mut buf).unwrap();
        assert!(n > 0, "closed before answering /metrics");
        answer.extend_from_slice(&buf[..n]);
        if let Some(end) = answer.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&answer[..end]).to_lowercase();
            let length = head
                .lines()
                .find_map(|l| l.strip_prefix("content-length:"))
                .and_then(|v| v.trim().parse::<usize>().ok())
                .expect("a content-length");
            break (end + 4, length);
        }
    };
    while answer.len() < head_end + length {
        let n = stream.read(&mut buf).unwrap();
        assert!(n > 0, "closed in the middle of /metrics");
        answer.extend_from_slice(&buf[..n]);
    }
    let body = String::from_utf8_lossy(&answer[head_end..head_end + length]).into_owned();
    let gauge = |slot: &str| {
        let name = format!("citymesh_connections_open{{slot=\"{slot}\"}} ");
        body.lines()
            .find_map(|l| l.strip_prefix(name.as_str()))
            .map_or(0, |v| v.trim().parse().unwrap())
    };
    (gauge("general"), gauge("reserved"))
}

/// Writes `head`, then trickles `body` a byte at a time, `pause` apart, reading between bytes;
/// answers the bytes sent of the body and what the server said (once it says anything).
fn trickle(addr: &str, head: &[u8], body: &[u8], pause: Duration) -> (usize, String) {
    let mut stream = TcpStream::connect(addr).unwrap();
    stream.write_all(head).unwrap();
    stream.set_read_timeout(Some(pause)).unwrap();
    let mut answer = Vec::new();
    let mut buf = [0u8; 4096];
    let mut sent = 0;
    loop {
        match stream.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                answer.extend_from_slice(&buf[..n]);
                if answer.windows(4).any(|w| w == b"\r\n\r\n") {
                    // The head is in; read what follows for a moment.
                    stream
                        .set_read_timeout(Some(Duration::from_millis(500)))
                        .unwrap();
                    while let Ok(n) = stream.read(&mut buf) {
                        if n == 0 {
                            break;
                        }
                        answer.extend_from_slice(&buf[..n]);
                    }
                    break;
                }
            }
            Err(_) if sent < body.len() => {
                if stream.write_all(&body[sent..=sent]).is_err() {
                    break;
                }
                sent += 1;
            }
            Err(_) => {
                // All sent: wait for the answer.
                stream
                    .set_read_timeout(Some(Duration::from_secs(30)))
                    .unwrap();
            }
        }
    }
    (sent, String::from_utf8_lossy(&answer).into_owned())
}

#[test]
fn d7_silent_connections_trickled_bodies_reserved_slots_and_early_413() {
    let db = tempfile::tempdir().unwrap();
    let (mut child, addr, log) = serve_binary(
        db.path(),
        &[
            "--first-byte-timeout-s",
            "1",
            "--header-timeout-s",
            "60",
            "--body-timeout-s",
            "1",
            "--idle-timeout-s",
            "120",
            "--request-timeout-s",
            "60",
            "--max-connections",
            "2",
            "--reserved-connections",
            "1",
        ],
    );
    std::thread::spawn(move || log.for_each(drop));
    // A connection that never sends a byte gives its slot back after the first-byte timeout,
    // long before the header (60 s) and idle (120 s) timeouts.
    let silent = TcpStream::connect(&addr).unwrap();
    assert!(
        closed_by_server(silent, Duration::from_secs(20)),
        "a silent connection held its slot"
    );

    // A body trickled a byte at a time is cut at the body deadline (1 s), not served for as long
    // as bytes keep coming.
    let body = vec![b' '; 400];
    let (sent, answer) = trickle(
        &addr,
        b"POST /classify HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n\
          Content-Length: 400\r\n\r\n",
        &body,
        Duration::from_millis(50),
    );
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("\"error\":\"timeout\""), "{answer}");
    assert!(
        sent < body.len(),
        "the whole trickled body was read: {sent}"
    );

    // An over-limit declared body with Expect: 100-continue is refused before any byte of it.
    let (sent, answer) = trickle(
        &addr,
        b"POST /scene.glb HTTP/1.1\r\nHost: x\r\nContent-Type: application/geo+json\r\n\
          Content-Length: 999999999\r\nExpect: 100-continue\r\n\r\n",
        b"",
        Duration::from_millis(50),
    );
    assert_eq!(sent, 0);
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(!answer.contains("100 Continue"), "{answer}");
    assert!(answer.contains("\"error\":\"too_large\""), "{answer}");

    // What hyper refuses before the router (a target of 65,535 bytes or more, over 1,000 header
    // lines, not HTTP) gets the same JSON error body as everything else.
    let raw = |request: Vec<u8>| {
        let mut c = TcpStream::connect(&addr).unwrap();
        c.write_all(&request).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut answer = Vec::new();
        let _ = c.read_to_end(&mut answer);
        String::from_utf8_lossy(&answer).into_owned()
    };
    let long = raw(format!("GET /{} HTTP/1.1\r\nHost: x\r\n\r\n", "a".repeat(70_000)).into_bytes());
    assert!(long.starts_with("HTTP/1.1 414"), "{long}");
    assert!(
        long.ends_with("}") && long.contains("\"error\":\"uri_too_long\""),
        "{long}"
    );
    let lines: String = (0..1_100).map(|i| format!("x-h{i}: 1\r\n")).collect();
    let many = raw(format!("GET /health HTTP/1.1\r\n{lines}\r\n").into_bytes());
    assert!(many.starts_with("HTTP/1.1 431"), "{many}");
    assert!(many.contains("\"error\":\"headers_too_large\""), "{many}");
    let garbage = raw(b"GARBAGE\r\n\r\n".to_vec());
    assert!(garbage.starts_with("HTTP/1.1 400"), "{garbage}");
    assert!(garbage.contains("\"error\":\"bad_request\""), "{garbage}");

    // Both general slots held by clients that send their headers slowly: /health still answers
    // on the reserved slot, and anything else there is a 503 that says why.
    // The connections above close on the server's side a moment after their answers. A
    // keep-alive client asks /metrics until it is the only connection open (every other slot
    // is free again), then starts a request it never finishes; the second client takes the
    // other general slot (clients are accepted in arrival order).
    let mut first = TcpStream::connect(&addr).unwrap();
    first
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut open = (0, 0);
    for _ in 0..10_000 {
        open = connections_open(&mut first);
        if open == (1, 0) {
            break;
        }
    }
    assert_eq!(open, (1, 0), "connections still open (general, reserved)");
    first.write_all(b"GET /health HTTP/1.1\r\n").unwrap();
    let mut second = TcpStream::connect(&addr).unwrap();
    second.write_all(b"GET /health HTTP/1.1\r\n").unwrap();
    let held = [first, second];
    let ask = |path: &str| {
        raw(format!("GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").into_bytes())
    };
    let health = ask("/health");
    assert!(health.starts_with("HTTP/1.1 200"), "{health}");
    let other = ask("/scene?bbox=8.400,49.010,8.401,49.011");
    assert!(other.starts_with("HTTP/1.1 503"), "{other}");
    assert!(
        other.contains("\"error\":\"busy\"") && other.to_lowercase().contains("retry-after"),
        "{other}"
    );
    drop(held);
    child.kill().unwrap();
    child.wait().unwrap();
}

#[tokio::test]
async fn too_many_header_lines_get_a_json_431() {
    let db = tempfile::tempdir().unwrap();
    let app = demo_app(&db, &[]).await;
    let mut request = Request::get("/health");
    for i in 0..150 {
        request = request.header(format!("x-h{i}"), "1");
    }
    let (status, _, body) = send(&app, request.body(Body::empty()).unwrap()).await;
    assert_eq!(status, StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE);
    assert_eq!(body["error"], "headers_too_large");
}

/// An Overpass answer with a dense city: `side` x `side` square buildings, each with a few
/// tags, about 12 m apart around 8.40 E, 49.01 N.
fn dense_city(side: usize) -> Vec<u8> {
    let mut elements = Vec::new();
    let mut node = 1_i64;
    for i in 0..side {
        for j in 0..side {
            let (lon, lat) = (8.40 + i as f64 * 1.6e-4, 49.01 + j as f64 * 1.1e-4);
            let mut nodes = Vec::new();
            for (dx, dy) in [(0.0, 0.0), (1e-4, 0.0), (1e-4, 7e-5), (0.0, 7e-5)] {
                elements
                    .push(json!({"type": "node", "id": node, "lon": lon + dx, "lat": lat + dy}));
                nodes.push(node);
                node += 1;
            }
            nodes.push(nodes[0]);
            elements.push(json!({
                "type": "way",
                "id": (i * side + j + 1) as i64,
                "nodes": nodes,
                "tags": {"building": "residential", "building:levels": "3", "roof:shape": "gabled",
                         "addr:street": "Hauptstraße", "addr:housenumber": format!("{j}")},
            }));
        }
    }
    serde_json::to_vec(&json!({ "elements": elements })).unwrap()
}

#[tokio::test]
async fn d8_memory_caches_stay_under_the_budget_with_a_dense_upstream() {
    let (upstream, url) = start_upstream(200, &[], dense_city(60)).await;
    let db = tempfile::tempdir().unwrap();
    let budget_mb = 16_u64;
    use clap::Parser;
    let args = citymesh::cli::ServeArgs::parse_from([
        "serve",
        "--dem-dir",
        dem_dir().to_str().unwrap(),
        "--cache-db",
        db.path().join("c.sqlite").to_str().unwrap(),
        "--overpass-url",
        &url,
        "--overpass-retries",
        "0",
        "--memory-mb",
        &budget_mb.to_string(),
        "--overpass-calls-per-minute",
        "1000",
    ]);
    let state = citymesh::server::build_state(&args).await.unwrap();
    let app = common::app_of(state.clone());
    // Long, thin boxes, each over its own list of data tiles (zoom 14, about 2.4 km wide).
    let mut weighed_most = 0;
    for k in 0..12 {
        let lat = 49.000 + f64::from(k) * 0.02;
        let uri = format!("/scene/stats?bbox=8.30,{lat:.3},8.40,{:.3}", lat + 0.001);
        let answer = get(&app, &uri).await;
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        let used = state.memory_use().await;
        let total: u64 = used.iter().map(|(_, b)| b).sum();
        assert!(
            total <= state.memory_budget.total,
            "after box {k}: {used:?} weigh {total} bytes, over the {budget_mb} MB budget"
        );
        let of = |name: &str| used.iter().find(|(n, _)| *n == name).unwrap().1;
        assert!(of("osm_tiles") <= state.memory_budget.osm_tiles, "{used:?}");
        assert!(
            of("building_sets") <= state.memory_budget.building_sets,
            "{used:?}"
        );
        weighed_most = weighed_most.max(of("osm_tiles") + of("building_sets"));
    }
    // The data did not fit: the caches filled to their shares and evicted.
    let fetched = upstream.requests.load(Ordering::SeqCst);
    assert!(fetched >= 24, "{fetched} data tiles fetched");
    let one_tile = citymesh_core::osm::read_buildings(&dense_city(60))
        .unwrap()
        .buildings
        .iter()
        .map(citymesh_core::osm::BuildingRecord::byte_size)
        .sum::<usize>() as u64;
    assert!(
        one_tile * fetched as u64 > state.memory_budget.total,
        "the test must hold more data than the budget"
    );
    assert!(
        weighed_most > state.memory_budget.osm_tiles / 2,
        "{weighed_most}"
    );
    // /metrics reports the same figures.
    let metrics = get(&app, "/metrics").await.text();
    assert!(
        metrics.contains(&format!(
            "citymesh_memory_cache_bytes{{cache=\"budget\"}} {}",
            budget_mb << 20
        )),
        "{metrics}"
    );
}

#[tokio::test]
async fn d11_the_osm_store_keeps_fetched_data_under_its_bound() {
    let db = tempfile::tempdir().unwrap();
    let body = dense_city(20);
    let (up, url) = start_upstream(200, &[], body.clone()).await;
    let app = online(
        &db,
        &url,
        &["--osm-store-mb", "1", "--overpass-calls-per-request", "36"],
    )
    .await;
    for tile in ["/tiles/13/4287/2811.glb", "/tiles/13/4290/2815.glb"] {
        let a = get(&app, tile).await;
        assert_eq!(a.status, StatusCode::OK, "{}", a.text());
    }
    let fetched = up.requests.load(Ordering::SeqCst) as u64;
    assert!(
        fetched * body.len() as u64 > 2 << 20,
        "the test must fetch more than the bound: {fetched} x {} bytes",
        body.len()
    );
    let pool =
        sqlx::SqlitePool::connect(&format!("sqlite:{}", db.path().join("c.sqlite").display()))
            .await
            .unwrap();
    let (rows, bytes): (i64, i64) = sqlx::query_as(
        "SELECT COUNT(*), COALESCE(SUM(length(body)), 0) FROM osm_data_tiles WHERE source = 'overpass'",
    )
    .fetch_one(&pool)
    .await
    .unwrap();
    assert!(bytes <= 1 << 20, "{rows} data tiles, {bytes} bytes stored");
    assert!((rows as u64) < fetched, "{rows} of {fetched} kept");
    assert!(rows > 0);
}

/// A square building about 440 x 330 m around 8.4 E, 49.0 N with `holes` small square
/// courtyards on a grid.
fn building_with_holes(holes: usize) -> Value {
    let (w, s, e, n) = (8.397, 48.9985, 8.403, 49.0015);
    let mut rings = vec![vec![[w, s], [e, s], [e, n], [w, n], [w, s]]];
    let side = (holes as f64).sqrt().ceil() as usize;
    for k in 0..holes {
        let (i, j) = ((k % side) as f64, (k / side) as f64);
        let x = w + (e - w) * (i + 0.3) / side as f64;
        let y = s + (n - s) * (j + 0.3) / side as f64;
        let (dx, dy) = ((e - w) * 0.4 / side as f64, (n - s) * 0.4 / side as f64);
        // Clockwise, as courtyards are.
        rings.push(vec![
            [x, y],
            [x, y + dy],
            [x + dx, y + dy],
            [x + dx, y],
            [x, y],
        ]);
    }
    json!({"type": "FeatureCollection", "features": [{"type": "Feature", "id": 7,
        "properties": {"building": "yes", "height": 12},
        "geometry": {"type": "Polygon", "coordinates": rings}}]})
}

#[tokio::test]
async fn d12_a_polygon_with_thousands_of_holes_is_refused_before_any_work() {
    let db = tempfile::tempdir().unwrap();
    let app = demo_app(&db, &[]).await;
    let (status, _, body) = send(&app, post_scene(building_with_holes(40_000))).await;
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{body}");
    assert_eq!(body["error"], "too_large");
    assert_eq!(body["feature"], 0);
    assert!(
        body["detail"].as_str().unwrap().contains("40000 holes")
            && body["detail"].as_str().unwrap().contains("at most 256"),
        "{body}"
    );
    // At the cap, the building is built, courtyards and all.
    let started = std::time::Instant::now();
    let response = app
        .clone()
        .oneshot(post_scene(building_with_holes(256)))
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let stats: Value = serde_json::from_str(
        response.headers()["x-citymesh-buildings"]
            .to_str()
            .unwrap_or("{}"),
    )
    .unwrap_or(Value::Null);
    let glb = response.into_body().collect().await.unwrap().to_bytes();
    common::assert_valid_glb(&glb);
    eprintln!(
        "a building with 256 courtyards: {} triangles in {:.0} ms ({stats})",
        common::glb_triangle_count(&glb),
        started.elapsed().as_secs_f64() * 1e3
    );
    // Each courtyard adds its walls: 4 walls of 2 triangles at least.
    assert!(common::glb_triangle_count(&glb) > 256 * 8);
}

/// An HTTP/2 client over TCP (prior knowledge, h2c) that has sent the preface and SETTINGS:
/// the request handle and a task driving the connection, which ends when the server closes it.
async fn h2_connect(
    addr: &str,
) -> (
    h2::client::SendRequest<bytes::Bytes>,
    h2::PingPong,
    tokio::task::JoinHandle<()>,
) {
    let tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
    let (send, mut connection) = h2::client::handshake(tcp).await.unwrap();
    let pings = connection.ping_pong().unwrap();
    let driver = tokio::spawn(async move {
        let _ = connection.await;
    });
    (send, pings, driver)
}

/// Sends PINGs one after another until the connection is gone.
fn keep_pinging(mut pings: h2::PingPong) -> tokio::task::JoinHandle<u64> {
    tokio::spawn(async move {
        let mut sent = 0;
        while pings.ping(h2::Ping::opaque()).await.is_ok() {
            sent += 1;
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        sent
    })
}

/// `GET path` over HTTP/2: the status and the body.
async fn h2_get(
    send: h2::client::SendRequest<bytes::Bytes>,
    addr: &str,
    path: &str,
) -> (u16, String) {
    let mut send = send.ready().await.unwrap();
    let request = Request::get(format!("http://{addr}{path}"))
        .body(())
        .unwrap();
    let (answer, _) = send.send_request(request, true).unwrap();
    let answer = answer.await.unwrap();
    let status = answer.status().as_u16();
    let mut body = answer.into_body();
    let mut bytes = Vec::new();
    while let Some(chunk) = body.data().await {
        let chunk = chunk.unwrap();
        let _ = body.flow_control().release_capacity(chunk.len());
        bytes.extend_from_slice(&chunk);
    }
    (status, String::from_utf8_lossy(&bytes).into_owned())
}

/// Round 3, item 1: HTTP/2 connections that open no stream are closed after the first-byte
/// timeout (not the idle one), PINGs or not, so they give every slot back, the reserved ones
/// too; and a connection with no open stream is idle whatever PINGs it sends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn h2_connections_without_streams_are_closed_pings_or_not() {
    let db = tempfile::tempdir().unwrap();
    let (mut child, addr, log) = serve_binary(
        db.path(),
        &[
            "--first-byte-timeout-s",
            "1",
            "--header-timeout-s",
            "60",
            "--idle-timeout-s",
            "600",
            "--request-timeout-s",
            "60",
            "--max-connections",
            "3",
            "--reserved-connections",
            "1",
        ],
    );
    std::thread::spawn(move || log.for_each(drop));
    // Every slot, general and reserved, taken by clients that only send the preface and
    // SETTINGS, two of them PINGing all the while.
    let mut held = Vec::new();
    for i in 0..4 {
        let (send, pings, driver) = h2_connect(&addr).await;
        let pinger = (i % 2 == 0).then(|| keep_pinging(pings));
        held.push((send, driver, pinger));
    }
    // The server closes all four (the idle timeout, 600 s, is far beyond this bound).
    for (_, driver, pinger) in held {
        tokio::time::timeout(Duration::from_secs(60), driver)
            .await
            .expect("an HTTP/2 connection with no stream was held open")
            .unwrap();
        if let Some(p) = pinger {
            assert!(p.await.unwrap() >= 1, "no PING went through");
        }
    }
    // The slots are free again: /health answers over HTTP/2.
    let (send, _pings, _driver) = h2_connect(&addr).await;
    let (status, body) = h2_get(send, &addr, "/health").await;
    assert_eq!(status, 200, "{body}");
    child.kill().unwrap();
    child.wait().unwrap();

    // After its request, a connection that only PINGs is idle: closed at the idle timeout (3 s)
    // though bytes keep flowing.
    let db = tempfile::tempdir().unwrap();
    let (mut child, addr, log) = serve_binary(
        db.path(),
        &["--idle-timeout-s", "3", "--request-timeout-s", "2"],
    );
    std::thread::spawn(move || log.for_each(drop));
    let (send, pings, driver) = h2_connect(&addr).await;
    let (status, _) = h2_get(send.clone(), &addr, "/health").await;
    assert_eq!(status, 200);
    let pinger = keep_pinging(pings);
    tokio::time::timeout(Duration::from_secs(60), driver)
        .await
        .expect("a PINGing HTTP/2 connection with no stream open was held")
        .unwrap();
    assert!(pinger.await.unwrap() >= 5, "too few PINGs to tell");
    drop(send);
    child.kill().unwrap();
    child.wait().unwrap();
}

/// Round 3, item 6: a generation's working memory grows with the outline nodes it draws (an
/// upstream with dense data made peaks of 3-5 times `--memory-mb`); `--max-scene-nodes` bounds
/// them per request. Kirchfeld's box at exactly its node count is drawn, one node less is
/// refused before any geometry is made, with the count.
#[tokio::test]
async fn a_generation_over_its_outline_node_budget_is_refused_with_its_count() {
    use citymesh_core::building::set::BuildingSet;
    use citymesh_core::scene::SceneArea;
    const KIRCHFELD: &str = "8.3877,49.0390,8.4039,49.0640";
    let records = citymesh_core::osm::read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let set = BuildingSet::new(records);
    let nodes = SceneArea::Bbox(KIRCHFELD.parse().unwrap())
        .request(&set)
        .unwrap()
        .outline_nodes();
    assert!(nodes > 10_000, "{nodes}");
    let pbf = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    for (budget, status) in [
        (nodes, StatusCode::OK),
        (nodes - 1, StatusCode::BAD_REQUEST),
    ] {
        let db = tempfile::tempdir().unwrap();
        let budget = budget.to_string();
        let app = app_with(
            &dem_dir(),
            &db.path().join("c.sqlite"),
            &["--osm", pbf.to_str().unwrap(), "--max-scene-nodes", &budget],
        )
        .await;
        let answer = get(&app, &format!("/scene.glb?bbox={KIRCHFELD}")).await;
        assert_eq!(answer.status, status, "budget {budget}");
        if status == StatusCode::BAD_REQUEST {
            let body = answer.json();
            assert_eq!(body["error"], "area_too_complex");
            let detail = body["detail"].as_str().unwrap();
            assert!(
                detail.contains(&format!("{nodes} outline nodes, more than the {budget}")),
                "{detail}"
            );
        }
    }
}

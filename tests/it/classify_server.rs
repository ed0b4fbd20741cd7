//! Roof classification through the server (docs/extensions.md section 1): `POST /classify` queues
//! the untagged buildings of Kirchfeld (its `roof:shape` tags stripped), workers classify them
//! from a real imagery server started inside the test on 127.0.0.1 (tiles citymesh's renderer
//! drew of the real footprints with the shapes their tags say), the predictions are compared with
//! the stripped tags, tiles with `roofs=classified` change, and a new prediction changes exactly
//! the tiles that hold its building. A server killed with SIGKILL in the middle of a run of more
//! than 1000 jobs, and started again, finishes every job exactly once.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use citymesh::cli::ServeArgs;
use citymesh::roofs::jobs::worker::WorkerConfig;
use citymesh::state::AppState;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, read_buildings, write_overpass_json};
use clap::Parser;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// About 500 x 650 m of Kirchfeld with many flat and gabled tags.
const AREA: &str = "8.396,49.052,8.403,49.058";

/// Kirchfeld as Overpass JSON with every `roof:shape` removed; answers the file and the removed
/// tags by OSM id.
fn stripped_kirchfeld(dir: &Path) -> (PathBuf, HashMap<String, String>) {
    let mut records: Vec<BuildingRecord> =
        read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings;
    let mut tags = HashMap::new();
    for r in &mut records {
        if let Some(shape) = r.tags.remove("roof:shape") {
            tags.insert(r.id.to_string(), shape);
        }
    }
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let path = dir.join("kirchfeld-stripped.json");
    std::fs::write(&path, write_overpass_json(&refs)).unwrap();
    (path, tags)
}

/// The app over the stripped file with the classifier, imagery at `imagery_url` and one worker.
/// A state with the classifier and imagery at `imagery_url`, a database in `db`, and `extra`
/// (where buildings come from, and more); no worker runs yet.
async fn classifier_state(db: &Path, imagery_url: &str, extra: &[&str]) -> AppState {
    let dem = common::dem_dir();
    let mut argv = vec![
        "serve".to_owned(),
        "--dem-dir".to_owned(),
        dem.to_str().unwrap().to_owned(),
        "--cache-db".to_owned(),
        db.join("c.sqlite").to_str().unwrap().to_owned(),
        "--roof-classifier".to_owned(),
        "--imagery-url".to_owned(),
        imagery_url.to_owned(),
    ];
    argv.extend(extra.iter().map(|a| (*a).to_owned()));
    citymesh::server::build_state(&ServeArgs::parse_from(argv))
        .await
        .unwrap()
}

async fn server(db: &Path, osm: &Path, imagery_url: &str) -> (axum::Router, AppState) {
    let osm = osm.to_str().unwrap();
    let extra = [
        "--osm",
        osm,
        "--imagery-id",
        "ortho",
        "--imagery-attribution",
        "rendered by citymesh",
    ];
    let state = classifier_state(db, imagery_url, &extra).await;
    assert!(state.classifier.is_some(), "the classifier did not load");
    state
        .generator
        .roofs
        .spawn_workers(1, WorkerConfig::default());
    (citymesh::app(state.clone()), state)
}

/// Polls a batch until no job is queued or running.
async fn wait_finished(app: &axum::Router, id: &str) -> serde_json::Value {
    let deadline = std::time::Instant::now() + Duration::from_secs(600);
    loop {
        let progress = common::get(app, &format!("/classify/{id}")).await;
        assert_eq!(progress.status, StatusCode::OK);
        let json = progress.json();
        if json["finished"] == true {
            return json;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "batch {id} did not finish: {json}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// The XYZ tile holding a point.
fn tile_of(lon: f64, lat: f64, z: u8) -> TileCoord {
    TileCoord::containing(z, lon, lat)
}

fn tile_uri(t: TileCoord, roofs: &str) -> String {
    format!("/tiles/{}/{}/{}.glb?roofs={roofs}", t.z, t.x, t.y)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stripped_kirchfeld_classified_through_the_api_agrees_with_its_tags_and_changes_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, tags) = stripped_kirchfeld(dir.path());
    let base = common::imagery::imagery_server().await;
    let (app, state) = server(
        dir.path(),
        &osm,
        &format!("{base}/ortho/{{z}}/{{x}}/{{y}}.png"),
    )
    .await;
    let area: GeoBbox = AREA.parse().unwrap();
    let centre = tile_of(
        (area.min_lon() + area.max_lon()) / 2.0,
        (area.min_lat() + area.max_lat()) / 2.0,
        16,
    );

    // Before any classification: the tile is served at once, with its untagged buildings pending.
    let before = common::get(&app, &tile_uri(centre, "classified")).await;
    assert_eq!(before.status, StatusCode::OK);
    let pending: usize = before
        .header("x-citymesh-roofs")
        .strip_prefix("partial, ")
        .and_then(|r| r.strip_suffix(" pending"))
        .unwrap_or_else(|| panic!("{}", before.header("x-citymesh-roofs")))
        .parse()
        .unwrap();
    assert!(pending > 50, "{pending}");
    let plain = common::get(&app, &tile_uri(centre, "osm")).await;
    assert!(plain.headers.get("x-citymesh-roofs").is_none());
    // No prediction yet: the same bytes as without the classifier.
    assert_eq!(before.body, plain.body);

    // Queue the area, with the tagged buildings (all of them, once stripped) and a bad request.
    let bad = common::post_json(&app, "/classify", serde_json::json!({"bbox": "nonsense"})).await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST, "{}", bad.json());
    let bad = common::post_json(&app, "/classify", serde_json::json!({"box": AREA})).await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
    assert!(bad.json()["detail"].as_str().unwrap().contains("bbox"));
    let created = common::post_json(&app, "/classify", serde_json::json!({"bbox": AREA})).await;
    assert_eq!(created.status, StatusCode::ACCEPTED, "{}", created.json());
    let created = created.json();
    let id = created["id"].as_str().unwrap().to_owned();
    let queued = created["counts"]["queued"].as_u64().unwrap();
    assert!(queued > 100, "{created}");
    assert_eq!(created["imagery_id"], "ortho");
    assert_eq!(created["imagery_attribution"], "rendered by citymesh");
    // The same area again: nothing new to queue.
    let again = common::post_json(&app, "/classify", serde_json::json!({"bbox": AREA})).await;
    assert_eq!(again.json()["counts"]["queued"], 0);
    assert_eq!(again.json()["counts"]["already"].as_u64().unwrap(), queued);

    let finished = wait_finished(&app, &id).await;
    assert_eq!(
        finished["jobs"]["done"].as_u64().unwrap(),
        queued,
        "{finished}"
    );
    assert_eq!(finished["percent_ended"], 100.0);

    // The predictions against the stripped tags.
    let answer = common::get(&app, &format!("/classify/predictions?bbox={AREA}")).await;
    assert_eq!(answer.status, StatusCode::OK);
    assert_eq!(answer.header("content-type"), "application/geo+json");
    let collection = answer.json();
    let features = collection["features"].as_array().unwrap();
    assert_eq!(features.len() as u64, queued);
    let mut confusion = [[0usize; 3]; 3];
    let classes = ["flat", "gabled", "hipped"];
    for f in features {
        let p = &f["properties"];
        let sum: f64 = classes
            .iter()
            .map(|c| p["probabilities"][c].as_f64().unwrap())
            .sum();
        assert!((sum - 1.0).abs() < 1e-4, "{p}");
        let tag = tags.get(p["osm_id"].as_str().unwrap()).map(String::as_str);
        let tag = match tag {
            Some("pyramidal") => Some("hipped"),
            t => t,
        };
        if let Some(t) = tag.and_then(|t| classes.iter().position(|c| *c == t)) {
            let q = classes
                .iter()
                .position(|c| *c == p["roof_shape"].as_str().unwrap())
                .unwrap();
            confusion[t][q] += 1;
        }
    }
    let compared: usize = confusion.iter().flatten().sum();
    let agree: usize = (0..3).map(|i| confusion[i][i]).sum();
    let share = agree as f64 / compared as f64;
    eprintln!(
        "agreement with the stripped roof:shape tags: {agree}/{compared} = {:.1} %; confusion \
         (rows: tag flat, gabled, hipped; columns: predicted): {confusion:?}",
        100.0 * share
    );
    assert!(compared >= 100, "{compared}");
    assert!(share >= 0.80, "{confusion:?}");
    // The predictions' own FeatureCollection names the same buildings: all classified already.
    let again = common::post_json(&app, "/classify", collection.clone()).await;
    assert_eq!(again.status, StatusCode::ACCEPTED, "{}", again.json());
    assert_eq!(again.json()["counts"]["queued"], 0);
    assert_eq!(again.json()["counts"]["already"].as_u64().unwrap(), queued);
    let no_id = common::post_json(
        &app,
        "/classify",
        serde_json::json!({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": null}]}),
    )
    .await;
    assert_eq!(no_id.status, StatusCode::BAD_REQUEST);
    assert!(no_id.json()["detail"].as_str().unwrap().contains("osm_id"));

    // Statistics with and without the classifier, side by side (the paper's Table 2).
    let stats = common::get(&app, &format!("/scene/stats?bbox={AREA}&roofs=classified")).await;
    assert_eq!(stats.status, StatusCode::OK);
    let stats = stats.json();
    let without = &stats["without_classifier"];
    eprintln!("with the classifier: {stats}\nwithout: {without}");
    assert_eq!(stats["roofs"], "classified");
    assert_eq!(without["roof_shape_from_tag_percent"], 0.0);
    assert_eq!(without["roof_shape_from_classifier_percent"], 0.0);
    assert!(
        stats["roof_shape_from_classifier_percent"]
            .as_f64()
            .unwrap()
            > 30.0
    );
    assert!(
        stats["flat_roof_percent"].as_f64().unwrap()
            < without["flat_roof_percent"].as_f64().unwrap()
    );
    assert!(stats["triangles"].as_u64().unwrap() > without["triangles"].as_u64().unwrap());
    assert!(
        stats["classified_roofs"]["classification_ms"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    assert_eq!(stats["imagery_attribution"], "rendered by citymesh");
    // The 3D Tiles pages carry it too, as a script string, shown with roofs=classified.
    for page in ["/cesium", "/3dtiles-renderer"] {
        let html = common::get(&app, page).await.text();
        assert!(
            html.contains("const imageryCredit = \"rendered by citymesh\";"),
            "{page}"
        );
    }
    let plain_stats = common::get(&app, &format!("/scene/stats?bbox={AREA}"))
        .await
        .json();
    assert_eq!(plain_stats["roofs"], "osm");
    assert!(plain_stats["without_classifier"].is_null());
    assert_eq!(plain_stats["triangles"], without["triangles"]);

    // The tile now has classified roofs.
    let after = common::get(&app, &tile_uri(centre, "classified")).await;
    assert_eq!(after.header("x-citymesh-cache"), "miss");
    let header = after.header("x-citymesh-roofs").to_owned();
    assert_ne!(after.body, plain.body);
    common::assert_valid_glb(&after.body);
    // Buildings of the tile outside the classified area are still pending.
    eprintln!("tile {centre:?} after classification: {header}");

    // A new prediction changes exactly the tiles that hold its building: pick a classified
    // building well inside one tile, and a tile with buildings elsewhere.
    let (moved_id, home) = features
        .iter()
        .find_map(|f| {
            let ring = f["geometry"]["coordinates"][0].as_array().unwrap();
            let lon = ring.iter().map(|p| p[0].as_f64().unwrap()).sum::<f64>() / ring.len() as f64;
            let lat = ring.iter().map(|p| p[1].as_f64().unwrap()).sum::<f64>() / ring.len() as f64;
            let t = tile_of(lon, lat, 17);
            let b = t.bounds();
            let margin = 0.25 * (b.max_lon() - b.min_lon());
            let inside = lon > b.min_lon() + margin
                && lon < b.max_lon() - margin
                && lat > b.min_lat() + margin * 0.66
                && lat < b.max_lat() - margin * 0.66;
            (inside && f["properties"]["confident"] == true)
                .then(|| (f["properties"]["osm_id"].as_str().unwrap().to_owned(), t))
        })
        .expect("a confident prediction well inside a z17 tile");
    let elsewhere = TileCoord::new(17, home.x + 2, home.y).unwrap();
    for t in [home, elsewhere] {
        common::get(&app, &tile_uri(t, "classified")).await;
        let cached = common::get(&app, &tile_uri(t, "classified")).await;
        assert_eq!(cached.header("x-citymesh-cache"), "hit");
    }
    let home_before = common::get(&app, &tile_uri(home, "classified")).await;
    let entry = state
        .generator
        .roofs
        .active()
        .index
        .with(|m| m.get(&moved_id).cloned())
        .unwrap();
    let old = entry.prediction.probabilities;
    // The same confidence, another class.
    let turned = [old[1], old[2], old[0]];
    state.generator.roofs.active().index.insert(
        moved_id.clone(),
        entry.footprint_hash.clone(),
        citymesh::roofs::classifier::Prediction::new(turned),
        1.0,
    );
    let home_after = common::get(&app, &tile_uri(home, "classified")).await;
    assert_eq!(home_after.header("x-citymesh-cache"), "miss", "{moved_id}");
    assert_ne!(home_after.body, home_before.body);
    let other = common::get(&app, &tile_uri(elsewhere, "classified")).await;
    assert_eq!(other.header("x-citymesh-cache"), "hit");
    // roofs=osm tiles never depend on predictions.
    let osm_tile = common::get(&app, &tile_uri(home, "osm")).await;
    common::get(&app, &tile_uri(home, "osm")).await;
    assert_eq!(
        common::get(&app, &tile_uri(home, "osm"))
            .await
            .header("x-citymesh-cache"),
        "hit"
    );
    assert_ne!(osm_tile.body, home_after.body);

    // Bad parameters.
    let bad = common::get(&app, &tile_uri(home, "guessed")).await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
    assert!(bad.json()["detail"].as_str().unwrap().contains("roofs"));
    for (uri, status) in [
        ("/classify/0", StatusCode::BAD_REQUEST),
        ("/classify/abc", StatusCode::BAD_REQUEST),
        ("/classify/999999", StatusCode::BAD_REQUEST),
        (
            "/classify/00000000000000000000000000000001",
            StatusCode::NOT_FOUND,
        ),
        ("/classify/predictions", StatusCode::BAD_REQUEST),
    ] {
        assert_eq!(common::get(&app, uri).await.status, status, "{uri}");
    }
    let cancel = common::send(
        &app,
        Request::delete(format!("/classify/{id}"))
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(cancel.status, StatusCode::OK);
    assert_eq!(cancel.json()["cancelled"], 0);
    assert_eq!(
        common::get(&app, &format!("/classify/{id}")).await.status,
        StatusCode::NOT_FOUND
    );
    let metrics = String::from_utf8(common::get(&app, "/metrics").await.body).unwrap();
    assert!(
        metrics.contains(&format!("citymesh_roof_jobs{{state=\"done\"}} {queued}")),
        "{metrics}"
    );
    assert!(metrics.contains("citymesh_imagery_fetches_total{result=\"ok\"}"));
    assert!(metrics.contains("citymesh_roof_inference_duration_seconds_count"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn classification_is_unavailable_without_classifier_or_imagery() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let app = common::app_with(
        &common::dem_dir(),
        &dir.path().join("c.sqlite"),
        &["--osm", osm.to_str().unwrap()],
    )
    .await;
    let answer = common::post_json(&app, "/classify", serde_json::json!({"bbox": AREA})).await;
    assert_eq!(answer.status, StatusCode::SERVICE_UNAVAILABLE);
    assert!(
        answer.json()["detail"]
            .as_str()
            .unwrap()
            .contains("--roof-classifier")
    );
    // So does adapting.
    let answer =
        common::post_json(&app, "/classify/adapt", serde_json::json!({"bbox": AREA})).await;
    assert_eq!(answer.status, StatusCode::SERVICE_UNAVAILABLE);
    // A body over the limit is 413, as documented, with a JSON body (was 400): a million ids.
    let ids: Vec<String> = (0..1_000_000).map(|i| format!("way/{i}")).collect();
    let answer = common::post_json(
        &app,
        "/classify",
        serde_json::json!({"bbox": AREA, "osm_ids": ids}),
    )
    .await;
    assert_eq!(
        answer.status,
        StatusCode::PAYLOAD_TOO_LARGE,
        "{}",
        answer.text()
    );
    assert_eq!(answer.json()["error"], "body_too_large");
    // Classified tiles still serve: every untagged building is pending.
    let t = tile_of(8.3995, 49.055, 16);
    let tile = common::get(&app, &tile_uri(t, "classified")).await;
    assert_eq!(tile.status, StatusCode::OK);
    assert!(tile.header("x-citymesh-roofs").starts_with("partial, "));
}

/// A job store's figures, read straight from the database.
async fn job_figures(db: &Path) -> (HashMap<String, i64>, i64, i64) {
    let pool = citymesh::db::open(db.to_str().unwrap()).await.unwrap();
    let states: Vec<(String, i64)> =
        sqlx::query_as("SELECT state, COUNT(*) FROM roof_jobs GROUP BY state")
            .fetch_all(&pool)
            .await
            .unwrap();
    let (predictions,): (i64,) = sqlx::query_as("SELECT COUNT(*) FROM roof_predictions")
        .fetch_one(&pool)
        .await
        .unwrap();
    let (attempts,): (i64,) = sqlx::query_as("SELECT COALESCE(SUM(attempts), 0) FROM roof_jobs")
        .fetch_one(&pool)
        .await
        .unwrap();
    (states.into_iter().collect(), predictions, attempts)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_killed_mid_run_finishes_every_job_exactly_once_after_a_restart() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let base = common::imagery::imagery_server().await;
    let grey = format!("{base}/grey/{{z}}/{{x}}/{{y}}.png");
    let args = [
        "--osm",
        osm.to_str().unwrap(),
        "--roof-classifier",
        "--imagery-url",
        &grey,
        "--classify-lease-s",
        "3",
    ];
    let start = || {
        let (child, addr, lines) = common::serve_binary(dir.path(), &args);
        // The log is drained so the server never blocks on a full pipe.
        std::thread::spawn(move || lines.for_each(drop));
        (child, format!("http://{addr}"))
    };
    let http = reqwest::Client::new();
    let (mut child, url) = start();
    let body = http
        .post(format!("{url}/classify"))
        .header("content-type", "application/json")
        .body(serde_json::json!({"bbox": "8.38,49.04,8.42,49.07"}).to_string())
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let created: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let id = created["id"].as_str().unwrap().to_owned();
    let queued = created["counts"]["queued"].as_i64().unwrap();
    assert!(queued >= 1000, "{created}");
    // Let a part of the run finish, then SIGKILL in the middle of it.
    let progress = |url: String| {
        let (http, id) = (http.clone(), id.clone());
        async move {
            let body = http
                .get(format!("{url}/classify/{id}"))
                .send()
                .await
                .unwrap()
                .bytes()
                .await
                .unwrap();
            serde_json::from_slice::<serde_json::Value>(&body).unwrap()
        }
    };
    loop {
        let p = progress(url.clone()).await;
        if p["jobs"]["done"].as_i64().unwrap() >= 200 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let db = dir.path().join("c.sqlite");
    let (states, predictions_at_kill, _) = job_figures(&db).await;
    let done_at_kill = states.get("done").copied().unwrap_or(0);
    assert!(done_at_kill < queued, "the run ended before the kill");
    assert_eq!(predictions_at_kill, done_at_kill);
    eprintln!("killed with {states:?}");

    // Started again: the jobs the dead worker held come back after their lease.
    let (mut child, url) = start();
    let deadline = std::time::Instant::now() + Duration::from_secs(900);
    loop {
        let p = progress(url.clone()).await;
        if p["finished"] == true {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "{p}");
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let (states, predictions, attempts) = job_figures(&db).await;
    eprintln!("after the restart: {states:?}, {predictions} predictions, {attempts} attempts");
    assert_eq!(states.get("done").copied(), Some(queued), "{states:?}");
    assert_eq!(states.len(), 1, "{states:?}");
    assert_eq!(predictions, queued);
    // Every job ran once, except those the killed worker held (one claim, at most 16 jobs), which
    // ran twice.
    assert!(attempts >= queued && attempts <= queued + 16, "{attempts}");
}

/// A request with an `Origin` header (and optionally a preflight's requested method).
async fn from_origin(
    app: &axum::Router,
    method: &str,
    uri: &str,
    origin: Option<&str>,
    preflight_of: Option<&str>,
) -> StatusCode {
    let mut request = Request::builder()
        .method(method)
        .uri(uri)
        .header("host", "citymesh.local:8080")
        .header("content-type", "application/json");
    if let Some(o) = origin {
        request = request.header("origin", o);
    }
    if let Some(m) = preflight_of {
        request = request.header("access-control-request-method", m);
    }
    let body = if method == "POST" {
        Body::from(serde_json::json!({ "bbox": AREA }).to_string())
    } else {
        Body::empty()
    };
    common::send(app, request.body(body).unwrap()).await.status
}

#[tokio::test]
async fn only_allowed_origins_may_change_state_from_a_browser_but_every_origin_may_read() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let app = common::app_with(
        &common::dem_dir(),
        &dir.path().join("c.sqlite"),
        &[
            "--osm",
            osm.to_str().unwrap(),
            "--cors-origin",
            "https://app.example",
        ],
    )
    .await;
    let evil = Some("https://evil.example");
    // Another site's page may not queue, cancel or adapt (no classifier here: a request let
    // through gets 503, one refused 403 before anything runs).
    let forbidden = StatusCode::FORBIDDEN;
    let through = StatusCode::SERVICE_UNAVAILABLE;
    assert_eq!(
        from_origin(&app, "POST", "/classify", evil, None).await,
        forbidden
    );
    assert_eq!(
        from_origin(&app, "POST", "/classify/adapt", evil, None).await,
        forbidden
    );
    assert_eq!(
        from_origin(&app, "DELETE", "/classify/1", evil, None).await,
        forbidden
    );
    assert_eq!(
        from_origin(&app, "OPTIONS", "/classify/1", evil, Some("DELETE")).await,
        forbidden
    );
    // The listed origin, the server's own pages and clients without Origin go through.
    let listed = Some("https://app.example");
    assert_eq!(
        from_origin(&app, "POST", "/classify", listed, None).await,
        through
    );
    let own = Some("http://citymesh.local:8080");
    assert_eq!(
        from_origin(&app, "POST", "/classify", own, None).await,
        through
    );
    assert_eq!(
        from_origin(&app, "POST", "/classify", None, None).await,
        through
    );
    assert_eq!(
        from_origin(&app, "OPTIONS", "/classify/1", listed, Some("DELETE")).await,
        StatusCode::OK
    );
    // Reading stays open to every origin.
    let predictions = format!("/classify/predictions?bbox={AREA}");
    assert_eq!(
        from_origin(&app, "GET", &predictions, evil, None).await,
        StatusCode::OK
    );
    assert_eq!(
        from_origin(&app, "OPTIONS", "/classify/predictions", evil, Some("GET")).await,
        StatusCode::OK
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_two_batches_share_survives_the_deletion_of_one() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let imagery = common::imagery::imagery_server().await;
    let imagery_url = format!("{imagery}/grey/{{z}}/{{x}}/{{y}}");
    let state = classifier_state(dir.path(), &imagery_url, &["--osm", osm.to_str().unwrap()]).await;
    let app = citymesh::app(state.clone());
    // No worker yet: both batches stay queued. B asks for the same buildings as A.
    let small = "8.3990,49.0540,8.4000,49.0550";
    let a = common::post_json(&app, "/classify", serde_json::json!({ "bbox": small })).await;
    assert_eq!(a.status, StatusCode::ACCEPTED, "{}", a.text());
    let a = a.json();
    let queued = a["counts"]["queued"].as_u64().unwrap();
    assert!(queued > 0);
    let b = common::post_json(&app, "/classify", serde_json::json!({ "bbox": small })).await;
    let b = b.json();
    assert_eq!(b["counts"]["already"].as_u64().unwrap(), queued);
    let b_id = b["id"].as_str().unwrap().to_owned();
    // B's progress counts the jobs A queued.
    let progress = common::get(&app, &format!("/classify/{b_id}")).await.json();
    assert_eq!(
        progress["jobs"]["queued"].as_u64().unwrap(),
        queued,
        "{progress}"
    );
    // Deleting A cancels nothing B still wants (before: all of them, and B "finished").
    let request = Request::delete(format!("/classify/{}", a["id"].as_str().unwrap()))
        .body(Body::empty())
        .unwrap();
    let deleted = common::send(&app, request).await;
    assert_eq!(deleted.status, StatusCode::OK, "{}", deleted.text());
    assert_eq!(deleted.json()["cancelled"], 0);
    let progress = common::get(&app, &format!("/classify/{b_id}")).await.json();
    assert_eq!(
        progress["jobs"]["queued"].as_u64().unwrap(),
        queued,
        "{progress}"
    );
    assert_eq!(progress["finished"], false);
    // A batch no other shares: deleting it cancels all its queued jobs, as before.
    let c = common::post_json(
        &app,
        "/classify",
        serde_json::json!({ "bbox": "8.3960,49.0520,8.3970,49.0530" }),
    )
    .await
    .json();
    let c_queued = c["counts"]["queued"].as_u64().unwrap();
    assert!(c_queued > 0);
    let request = Request::delete(format!("/classify/{}", c["id"].as_str().unwrap()))
        .body(Body::empty())
        .unwrap();
    assert_eq!(
        common::send(&app, request).await.json()["cancelled"],
        c_queued
    );
    // A worker then does B's jobs.
    state
        .generator
        .roofs
        .spawn_workers(1, WorkerConfig::default());
    let done = wait_finished(&app, &b_id).await;
    let ended = done["jobs"]["done"].as_u64().unwrap() + done["jobs"]["failed"].as_u64().unwrap();
    assert_eq!(ended, queued, "{done}");
    assert_eq!(done["jobs"]["cancelled"], 0);
}

/// Buildings (not parts) of `records` whose box's centre lies in `bbox` and that carry
/// `roof:shape`.
fn tagged_in(records: &[BuildingRecord], bbox: &GeoBbox) -> u64 {
    records
        .iter()
        .filter(|r| !r.is_part && r.tags.contains_key("roof:shape"))
        .filter(|r| {
            let [w, s, e, n] = citymesh_core::building::cluster::record_bounds(r);
            bbox.contains((w + e) / 2.0, (s + n) / 2.0)
        })
        .count() as u64
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_flood_of_district_batches_answers_no_500_and_cached_tiles_keep_being_served() {
    let dir = tempfile::tempdir().unwrap();
    let osm = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let records = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let imagery = common::imagery::imagery_server().await;
    let imagery_url = format!("{imagery}/grey/{{z}}/{{x}}/{{y}}");
    let state = classifier_state(dir.path(), &imagery_url, &["--osm", osm.to_str().unwrap()]).await;
    let app = citymesh::app(state.clone());

    // counts.skipped counts the box's buildings only: exactly the tagged ones in it.
    let small: GeoBbox = AREA.parse().unwrap();
    let answer = common::post_json(&app, "/classify", serde_json::json!({ "bbox": AREA })).await;
    assert_eq!(answer.status, StatusCode::ACCEPTED, "{}", answer.text());
    let counts = &answer.json()["counts"];
    assert_eq!(
        counts["skipped"]["tagged"].as_u64(),
        Some(tagged_in(&records, &small))
    );
    assert!(tagged_in(&records, &small) > 20);

    // Cached tiles, in SQLite only.
    let tiles: Vec<String> = (0..8)
        .map(|i| format!("/tiles/17/{}/{}.glb", 68593 + i % 4, 44969 + i / 4))
        .collect();
    for t in &tiles {
        assert_eq!(common::get(&app, t).await.status, StatusCode::OK, "{t}");
    }
    state.tiles.flush().await;
    state.tiles.invalidate_memory();

    // 16 batches over the whole district at once (thousands of upserts each), and tile reads
    // meanwhile.
    let district = "8.380,49.040,8.420,49.070";
    let posts: Vec<_> = (0..16)
        .map(|_| {
            let app = app.clone();
            tokio::spawn(async move {
                common::post_json(&app, "/classify", serde_json::json!({ "bbox": district })).await
            })
        })
        .collect();
    let reads: Vec<_> = (0..8)
        .map(|k| {
            let (app, tiles) = (app.clone(), tiles.clone());
            tokio::spawn(async move {
                let mut out = Vec::new();
                for round in 0..21 {
                    let t = &tiles[(k + round) % tiles.len()];
                    let started = std::time::Instant::now();
                    let status = common::get(&app, t).await.status;
                    out.push((status, started.elapsed()));
                }
                out
            })
        })
        .collect();
    let mut statuses: HashMap<u16, usize> = HashMap::new();
    for p in posts {
        let answer = p.await.unwrap();
        *statuses.entry(answer.status.as_u16()).or_default() += 1;
        if answer.status == StatusCode::SERVICE_UNAVAILABLE {
            assert!(!answer.header("retry-after").is_empty());
            assert_eq!(answer.json()["error"], "database_busy");
        }
    }
    let mut latencies = Vec::new();
    for r in reads {
        for (status, took) in r.await.unwrap() {
            assert_eq!(
                status,
                StatusCode::OK,
                "a cached tile failed under write load"
            );
            latencies.push(took);
        }
    }
    latencies.sort();
    let p99 = latencies[latencies.len() * 99 / 100];
    eprintln!(
        "16 district batches at once: answers by status {statuses:?}; {} cached tile reads \
         meanwhile, p99 {:.1} ms",
        latencies.len(),
        p99.as_secs_f64() * 1e3
    );
    assert_eq!(statuses.get(&500), None, "{statuses:?}");
    assert_eq!(
        statuses.get(&202).copied().unwrap_or(0) + statuses.get(&503).copied().unwrap_or(0),
        16
    );
}

#[tokio::test]
async fn post_classify_gathers_its_buildings_within_the_request_timeout() {
    // An Overpass that takes 3 s to answer; requests may take 1 s.
    async fn slow() -> &'static str {
        tokio::time::sleep(Duration::from_secs(3)).await;
        r#"{"elements": []}"#
    }
    let stub = axum::Router::new().route("/api/interpreter", axum::routing::post(slow));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let overpass = format!("http://{}/api/interpreter", listener.local_addr().unwrap());
    tokio::spawn(async move { axum::serve(listener, stub).await.unwrap() });
    let imagery = common::imagery::imagery_server().await;
    let dir = tempfile::tempdir().unwrap();
    let imagery_url = format!("{imagery}/grey/{{z}}/{{x}}/{{y}}");
    let state = classifier_state(
        dir.path(),
        &imagery_url,
        &["--overpass-url", &overpass, "--request-timeout-s", "1"],
    )
    .await;
    let app = citymesh::app(state.clone());
    // POST /classify and POST /classify/adapt alike (round 3: the adaptation waited 60 s).
    for route in ["/classify", "/classify/adapt"] {
        let answer = common::post_json(&app, route, serde_json::json!({ "bbox": AREA })).await;
        assert_eq!(
            answer.status,
            StatusCode::SERVICE_UNAVAILABLE,
            "{route}: {}",
            answer.text()
        );
        assert_eq!(answer.json()["error"], "timeout");
        assert!(!answer.header("retry-after").is_empty());
    }
    // The adaptation that timed out is recorded as failed, so the next one may start.
    let imagery_id = state.generator.roofs.imagery_id.clone();
    assert_eq!(
        state
            .generator
            .roofs
            .adaptations
            .running(&imagery_id)
            .await
            .unwrap(),
        None
    );
}

/// Round 3, item 2: what classification batches keep in the store is bounded. One client past
/// its share gets 429, everyone past the whole budget 503, both with Retry-After; deleting a
/// batch gives its bytes back; finished batches expire.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn classification_batches_stay_within_their_budget_and_expire() {
    use citymesh::roofs::jobs::batch_budget::batch_bytes;
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let imagery = common::imagery::imagery_server().await;
    let imagery_url = format!("{imagery}/grey/{{z}}/{{x}}/{{y}}");
    // A budget of 1 MiB, a client's share of half of it; finished batches expire at once.
    let extra = [
        "--osm",
        osm.to_str().unwrap(),
        "--classify-store-mb",
        "1",
        "--classify-client-share-percent",
        "50",
        "--classify-batch-ttl-s",
        "0",
    ];
    let state = classifier_state(dir.path(), &imagery_url, &extra).await;
    let app = citymesh::app(state.clone());
    let first = common::post_json(&app, "/classify", serde_json::json!({ "bbox": AREA })).await;
    assert_eq!(first.status, StatusCode::ACCEPTED, "{}", first.text());
    let first = first.json();
    let links =
        first["counts"]["queued"].as_u64().unwrap() + first["counts"]["already"].as_u64().unwrap();
    let bytes = batch_bytes(links as usize);
    assert!(bytes > 4096, "{bytes} bytes: too small an area to tell");
    // The same box again and again: as many as fit in half a MiB, then 429.
    let share = (1u64 << 20) / 2;
    let fit = share / bytes;
    let mut ids = vec![first["id"].as_str().unwrap().to_owned()];
    for i in 1..fit {
        let again = common::post_json(&app, "/classify", serde_json::json!({ "bbox": AREA })).await;
        assert_eq!(
            again.status,
            StatusCode::ACCEPTED,
            "batch {i}: {}",
            again.text()
        );
        ids.push(again.json()["id"].as_str().unwrap().to_owned());
    }
    let over = common::post_json(&app, "/classify", serde_json::json!({ "bbox": AREA })).await;
    assert_eq!(
        over.status,
        StatusCode::TOO_MANY_REQUESTS,
        "{}",
        over.text()
    );
    assert_eq!(over.json()["error"], "too_many_batches");
    assert!(!over.header("retry-after").is_empty());
    let (all, mine) = state.generator.roofs.batches.usage("local").await.unwrap();
    assert_eq!((all, mine), (fit * bytes, fit * bytes));
    let delete = |id: String| {
        let app = app.clone();
        async move {
            let request = axum::http::Request::delete(format!("/classify/{id}"))
                .body(axum::body::Body::empty())
                .unwrap();
            let answer = common::send(&app, request).await;
            assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        }
    };
    // Deleting a batch gives its links back at once.
    delete(ids.remove(0)).await;
    let (all, _) = state.generator.roofs.batches.usage("local").await.unwrap();
    assert_eq!(all, (fit - 1) * bytes + batch_bytes(0));
    let again = common::post_json(&app, "/classify", serde_json::json!({ "bbox": AREA })).await;
    assert_eq!(again.status, StatusCode::ACCEPTED, "{}", again.text());
    ids.push(again.json()["id"].as_str().unwrap().to_owned());
    // Once their jobs have ended (no worker runs here: deleting cancels them), batches expire at
    // the next sweep, and the store keeps nothing of them.
    let last = ids.last().unwrap().clone();
    for id in ids {
        delete(id).await;
    }
    let expired = state
        .generator
        .roofs
        .batches
        .expire(i64::MAX)
        .await
        .unwrap();
    assert_eq!(expired, fit);
    assert_eq!(
        state.generator.roofs.batches.usage("local").await.unwrap(),
        (0, 0)
    );
    let gone = common::get(&app, &format!("/classify/{last}")).await;
    assert_eq!(gone.status, StatusCode::NOT_FOUND, "{}", gone.text());
    let text = gone.text();
    assert!(
        text.contains("expired") || text.contains("finished batches are kept"),
        "{text}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_round_on_slow_imagery_keeps_its_jobs_and_each_is_done_once() {
    let dir = tempfile::tempdir().unwrap();
    let (osm, _) = stripped_kirchfeld(dir.path());
    let imagery = common::imagery::imagery_server().await;
    let imagery_url = format!("{imagery}/slow/{{z}}/{{x}}/{{y}}");
    let state = classifier_state(dir.path(), &imagery_url, &["--osm", osm.to_str().unwrap()]).await;
    let app = citymesh::app(state.clone());
    let small = "8.3990,49.0540,8.4000,49.0550";
    let created = common::post_json(&app, "/classify", serde_json::json!({ "bbox": small })).await;
    assert_eq!(created.status, StatusCode::ACCEPTED, "{}", created.text());
    let created = created.json();
    let queued = created["counts"]["queued"].as_i64().unwrap();
    assert!(queued >= 8, "{created}");
    // Two workers; every imagery tile takes a second, longer than a lease: a round outlasts its
    // lease unless the lease is extended, and the other worker would take its jobs.
    state.generator.roofs.spawn_workers(
        2,
        WorkerConfig {
            claim: 64,
            lease: Duration::from_millis(1500),
            idle: Duration::from_millis(100),
        },
    );
    let finished = wait_finished(&app, created["id"].as_str().unwrap()).await;
    assert_eq!(
        finished["jobs"]["done"].as_i64(),
        Some(queued),
        "{finished}"
    );
    let (_, predictions, attempts) = job_figures(&dir.path().join("c.sqlite")).await;
    assert_eq!(predictions, queued);
    assert_eq!(
        attempts, queued,
        "a job was claimed again while its round ran"
    );
}

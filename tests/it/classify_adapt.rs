//! Adapting the roof classifier to an imagery source from OpenStreetMap's own tags
//! (docs/extensions.md section 3), through the server: an imagery server started by the test draws
//! Kirchfeld in a style the model was never trained on (blurred, bands rotated and inverted, as
//! a false-colour sensor might give), each
//! building with a roof shape the test assigns (a third each of flat, gabled and hipped, by id).
//! The west part of the area keeps those shapes as `roof:shape` tags (the examples), the east
//! part has none (the buildings to classify). `POST /classify/adapt` on the west part fits a head;
//! the east part's buildings are classified before and after, and the adapted head gets more of
//! them right (exact counts), and a tile there changes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh::roofs::jobs::worker::WorkerConfig;
use citymesh_core::geo::TileCoord;
use citymesh_core::osm::{BuildingRecord, read_buildings, write_overpass_json};
use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

/// The examples: the west part of the area.
const WEST: &str = "8.3960,49.0520,8.3995,49.0580";
/// The buildings to classify: the east part.
const EAST: &str = "8.3995,49.0520,8.4030,49.0580";
/// East buildings the shipped head gets right, and the adapted head.
const SHIPPED_RIGHT: usize = 146;
const ADAPTED_RIGHT: usize = 197;

/// The shape the test gives a building: a third each, by its id.
fn assigned(id: &str) -> &'static str {
    let h = xxhash_rust::xxh3::xxh3_64(id.as_bytes());
    ["flat", "gabled", "hipped"][(h % 3) as usize]
}

fn centre(r: &BuildingRecord) -> Option<[f64; 2]> {
    let nodes = &r.outers.first()?.nodes;
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for n in nodes {
        lo = [lo[0].min(n.lon), lo[1].min(n.lat)];
        hi = [hi[0].max(n.lon), hi[1].max(n.lat)];
    }
    Some([(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0])
}

/// The buildings of an OSM file.
fn osm_records(path: &Path) -> Vec<BuildingRecord> {
    read_buildings(&std::fs::read(path).unwrap())
        .unwrap()
        .buildings
}

/// The id and centre of the first building (not a part) whose centre lies in `bbox`.
fn truth_point(records: &[BuildingRecord], bbox: &str) -> (String, [f64; 2]) {
    records
        .iter()
        .filter(|r| !r.is_part)
        .find_map(|r| {
            let c = centre(r)?;
            inside(bbox, c).then(|| (r.id.to_string(), c))
        })
        .unwrap()
}

fn inside(bbox: &str, p: [f64; 2]) -> bool {
    let b: Vec<f64> = bbox.split(',').map(|v| v.parse().unwrap()).collect();
    p[0] >= b[0] && p[0] < b[2] && p[1] >= b[1] && p[1] < b[3]
}

/// Kirchfeld with the assigned shapes (what the imagery draws), and the file the server reads:
/// tags kept in the west part only.
fn kirchfeld(
    dir: &Path,
) -> (
    Vec<BuildingRecord>,
    std::path::PathBuf,
    HashMap<String, String>,
) {
    let mut truth: Vec<BuildingRecord> =
        read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings;
    let mut shapes = HashMap::new();
    for r in &mut truth {
        r.tags.retain(|k, _| !k.starts_with("roof:"));
        if !r.is_part {
            let id = r.id.to_string();
            let shape = assigned(&id);
            r.tags.insert("roof:shape".into(), shape.into());
            shapes.insert(id, shape.to_owned());
        }
    }
    let served: Vec<BuildingRecord> = truth
        .iter()
        .cloned()
        .map(|mut r| {
            if !centre(&r).is_some_and(|c| inside(WEST, c)) {
                r.tags.remove("roof:shape");
            }
            r
        })
        .collect();
    let refs: Vec<&BuildingRecord> = served.iter().collect();
    let path = dir.join("kirchfeld-half-tagged.json");
    std::fs::write(&path, write_overpass_json(&refs)).unwrap();
    (truth, path, shapes)
}

/// Classifies the east part and waits; answers how many of its predictions by the model now in
/// use match the assigned shapes, of how many.
async fn classify_east(
    app: &axum::Router,
    shapes: &HashMap<String, String>,
    bbox: serde_json::Value,
) -> (usize, usize) {
    let created = common::post_json(app, "/classify", serde_json::json!({ "bbox": bbox })).await;
    assert_eq!(created.status, StatusCode::ACCEPTED, "{}", created.text());
    let batch = created.json();
    let model_id = batch["model_id"].as_str().unwrap().to_owned();
    let id = batch["id"].as_str().unwrap().to_owned();
    let deadline = std::time::Instant::now() + Duration::from_secs(600);
    loop {
        let progress = common::get(app, &format!("/classify/{id}")).await.json();
        if progress["finished"] == true {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "{progress}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let predictions = common::get(app, &format!("/classify/predictions?bbox={EAST}"))
        .await
        .json();
    let (mut right, mut total) = (0, 0);
    for f in predictions["features"].as_array().unwrap() {
        let p = &f["properties"];
        if p["model_id"] != model_id.as_str() {
            continue;
        }
        let truth = &shapes[p["osm_id"].as_str().unwrap()];
        total += 1;
        right += usize::from(p["roof_shape"] == truth.as_str());
    }
    (right, total)
}

/// The XYZ tile holding a point.
fn tile_of(lon: f64, lat: f64, z: u8) -> TileCoord {
    TileCoord::containing(z, lon, lat)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn adapting_on_the_tagged_roofs_of_an_area_classifies_its_untagged_roofs_better() {
    let dir = tempfile::tempdir().unwrap();
    let (truth, osm, shapes) = kirchfeld(dir.path());
    let imagery = common::imagery::styled_imagery_server(truth).await;
    let args = common::imagery::classifying_args(
        &dir.path().join("c.sqlite"),
        &osm,
        &format!("{imagery}/styled/{{z}}/{{x}}/{{y}}"),
        "styled",
    );
    let state = citymesh::server::build_state(&args).await.unwrap();
    assert!(state.classifier.is_some(), "the classifier did not load");
    state
        .generator
        .roofs
        .spawn_workers(1, WorkerConfig::default());
    let app = citymesh::app(state.clone());
    let tile = tile_of(8.4012, 49.0550, 17);
    let tile_uri = format!(
        "/tiles/{}/{}/{}.glb?roofs=classified",
        tile.z, tile.x, tile.y
    );

    let (shipped_right, shipped_total) = classify_east(&app, &shapes, EAST.into()).await;
    let before = common::get(&app, &tile_uri).await;
    assert_eq!(before.status, StatusCode::OK);

    // A box array of three numbers is no box.
    let bad = common::post_json(
        &app,
        "/classify",
        serde_json::json!({"bbox": [8.3995, 49.0520, 8.4030]}),
    )
    .await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST, "{}", bad.text());

    // Too small an area: said at once, nothing changes.
    let small = common::post_json(
        &app,
        "/classify/adapt",
        serde_json::json!({"bbox": "8.3960,49.0520,8.3965,49.0525"}),
    )
    .await;
    assert_eq!(
        small.status,
        StatusCode::UNPROCESSABLE_ENTITY,
        "{}",
        small.text()
    );
    assert!(small.text().contains("at least 20"), "{}", small.text());

    let created =
        common::post_json(&app, "/classify/adapt", serde_json::json!({"bbox": WEST})).await;
    assert_eq!(created.status, StatusCode::ACCEPTED, "{}", created.text());
    let created = created.json();
    let id = created["id"].as_str().unwrap().to_owned();
    assert_eq!(id.len(), 32);
    let examples = &created["examples"];
    eprintln!("examples {examples}");
    let deadline = std::time::Instant::now() + Duration::from_secs(600);
    let status = loop {
        let status = common::get(&app, &format!("/classify/adapt/{id}")).await;
        assert_eq!(status.status, StatusCode::OK, "{}", status.text());
        let status = status.json();
        if status["state"] != "running" {
            break status;
        }
        assert!(std::time::Instant::now() < deadline, "{status}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    eprintln!("adaptation: {status}");
    assert_eq!(status["state"], "done", "{status}");
    assert_eq!(status["percent"], 100.0);
    let head_id = status["head_id"].as_str().unwrap();
    assert!(status["report"]["accuracy"].as_f64().unwrap() > 0.0);

    // The box as a GeoJSON-style array this time.
    let east: Vec<f64> = EAST.split(',').map(|v| v.parse().unwrap()).collect();
    let (adapted_right, adapted_total) = classify_east(&app, &shapes, east.into()).await;
    eprintln!(
        "east: shipped head {shipped_right}/{shipped_total} right, adapted head \
         {adapted_right}/{adapted_total}"
    );
    assert_eq!(adapted_total, shipped_total);
    assert_eq!(
        (shipped_right, adapted_right),
        (SHIPPED_RIGHT, ADAPTED_RIGHT)
    );
    assert!(adapted_right > shipped_right);
    let active = state.generator.roofs.active();
    assert!(active.model_id.ends_with(&format!("+head-{head_id}")));

    // A FeatureCollection naming one east building by a point (its centre): the box around a
    // point is widened to reach it (before: "minLon must be smaller than maxLon").
    let (id, point) = truth_point(&osm_records(&osm), EAST);
    let named = common::post_json(
        &app,
        "/classify",
        serde_json::json!({"type": "FeatureCollection", "features": [{"type": "Feature",
            "geometry": {"type": "Point", "coordinates": point},
            "properties": {"osm_id": id}}]}),
    )
    .await;
    assert_eq!(named.status, StatusCode::ACCEPTED, "{}", named.text());
    let counts = &named.json()["counts"];
    assert_eq!(
        counts["queued"].as_u64().unwrap() + counts["already"].as_u64().unwrap(),
        1,
        "{counts}"
    );

    let after = common::get(&app, &tile_uri).await;
    assert_eq!(after.status, StatusCode::OK);
    assert_ne!(
        after.body, before.body,
        "the tile changes with the adapted head's roofs"
    );

    // Unknown and malformed ids.
    let missing = common::get(&app, "/classify/adapt/0123456789abcdef0123456789abcdef").await;
    assert_eq!(missing.status, StatusCode::NOT_FOUND);
    let bad = common::get(&app, "/classify/adapt/42").await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
}

/// Runs the citymesh binary off the runtime's threads (the imagery server runs on them).
async fn citymesh(args: &[&str]) -> std::process::Output {
    let args: Vec<String> = args.iter().map(|a| (*a).to_owned()).collect();
    tokio::task::spawn_blocking(move || {
        std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
            .args(&args)
            .output()
            .unwrap()
    })
    .await
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn adapt_roofs_from_osm_files_stores_a_head_the_server_then_uses() {
    let dir = tempfile::tempdir().unwrap();
    let (truth, osm, _) = kirchfeld(dir.path());
    let imagery = common::imagery::styled_imagery_server(truth).await;
    let db = dir.path().join("c.sqlite");
    let head = dir.path().join("head.json");
    let url = format!("{imagery}/styled/{{z}}/{{x}}/{{y}}");
    let out = citymesh(&[
        "adapt-roofs",
        "--quiet",
        "--osm",
        osm.to_str().unwrap(),
        "--bbox",
        WEST,
        "--imagery-url",
        &url,
        "--imagery-id",
        "styled",
        "--cache-db",
        db.to_str().unwrap(),
        "-o",
        head.to_str().unwrap(),
    ])
    .await;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!("adapt-roofs: {report}");
    assert_eq!(report["examples"]["flat"], 86);
    assert_eq!(report["examples"]["gabled"], 59);
    assert_eq!(report["examples"]["hipped"], 55);
    let head_id = report["head_id"].as_str().unwrap();
    assert!(head.is_file());

    // A server on the same database and imagery uses the stored head from the start.
    let args = common::imagery::classifying_args(&db, &osm, &url, "styled");
    let state = citymesh::server::build_state(&args).await.unwrap();
    let active = state.generator.roofs.active();
    assert!(
        active.model_id.ends_with(&format!("+head-{head_id}")),
        "{}",
        active.model_id
    );
    // Another imagery id keeps the shipped head.
    let mut other = args.clone();
    other.imagery.imagery_id = "other".into();
    let state = citymesh::server::build_state(&other).await.unwrap();
    assert!(!state.generator.roofs.active().model_id.contains("+head-"));

    // Too few examples: said, exit 1, nothing written.
    let none = dir.path().join("none.json");
    let out = citymesh(&[
        "adapt-roofs",
        "--quiet",
        "--osm",
        osm.to_str().unwrap(),
        "--bbox",
        "8.3960,49.0520,8.3965,49.0525",
        "--imagery-url",
        &url,
        "--cache-db",
        db.to_str().unwrap(),
        "-o",
        none.to_str().unwrap(),
    ])
    .await;
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("at least 20"));
    assert!(!none.exists());
}

/// Round 3, item 3: of 16 concurrent `POST /classify/adapt` for one imagery, one starts and 15
/// get 409 before gathering anything; `DELETE` cancels the running one, and a new one may start;
/// the server's shutdown stops it and records why.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_adaptation_runs_at_a_time_and_cancel_and_shutdown_stop_it() {
    let dir = tempfile::tempdir().unwrap();
    let (truth, osm, _) = kirchfeld(dir.path());
    let imagery = common::imagery::styled_imagery_server(truth).await;
    let args = common::imagery::classifying_args(
        &dir.path().join("c.sqlite"),
        &osm,
        &format!("{imagery}/styled/{{z}}/{{x}}/{{y}}"),
        "styled",
    );
    let state = citymesh::server::build_state(&args).await.unwrap();
    let app = citymesh::app(state.clone());
    let posts = (0..16).map(|_| {
        let app = app.clone();
        tokio::spawn(async move {
            common::post_json(&app, "/classify/adapt", serde_json::json!({"bbox": WEST})).await
        })
    });
    let mut started = Vec::new();
    let mut conflicts = 0;
    for post in posts.collect::<Vec<_>>() {
        let answer = post.await.unwrap();
        match answer.status {
            StatusCode::ACCEPTED => started.push(answer.json()["id"].as_str().unwrap().to_owned()),
            StatusCode::CONFLICT => {
                assert_eq!(answer.json()["error"], "adaptation_running");
                conflicts += 1;
            }
            other => panic!("{other}: {}", answer.text()),
        }
    }
    assert_eq!((started.len(), conflicts), (1, 15));
    let id = started.pop().unwrap();
    let delete = |id: String| {
        let app = app.clone();
        async move {
            let request = axum::http::Request::delete(format!("/classify/adapt/{id}"))
                .body(axum::body::Body::empty())
                .unwrap();
            common::send(&app, request).await
        }
    };
    let cancelled = delete(id.clone()).await;
    assert_eq!(cancelled.status, StatusCode::OK, "{}", cancelled.text());
    assert_eq!(cancelled.json()["state"], "cancelled");
    // Deleted: it is gone from the API (schemathesis' stateful check, ST301), and deleting it
    // again finds nothing.
    let gone = common::get(&app, &format!("/classify/adapt/{id}")).await;
    assert_eq!(gone.status, StatusCode::NOT_FOUND, "{}", gone.text());
    assert_eq!(gone.json()["error"], "no_such_adaptation");
    assert!(
        gone.text().contains("cancelled by DELETE"),
        "{}",
        gone.text()
    );
    assert_eq!(delete(id).await.status, StatusCode::NOT_FOUND);
    // Another may start now; the shutdown stops it and says so.
    let next = common::post_json(&app, "/classify/adapt", serde_json::json!({"bbox": WEST})).await;
    assert_eq!(next.status, StatusCode::ACCEPTED, "{}", next.text());
    let next = next.json()["id"].as_str().unwrap().to_owned();
    state
        .generator
        .roofs
        .shut_down(Duration::from_secs(120))
        .await;
    let status = common::get(&app, &format!("/classify/adapt/{next}"))
        .await
        .json();
    assert_eq!(status["state"], "failed", "{status}");
    assert!(
        status["error"].as_str().unwrap().contains("shutdown"),
        "{status}"
    );
    assert_eq!(
        state
            .generator
            .roofs
            .adaptations
            .running("styled")
            .await
            .unwrap(),
        None
    );
}

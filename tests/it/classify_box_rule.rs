//! One rule for which buildings a box holds (the core's `building::in_box`): `POST /classify`
//! and `citymesh classify` queue the same buildings for the same box. The command used to take
//! the buildings whose first node lay in the box, the server those whose centre did.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh::cli::ClassifyArgs;
use citymesh_core::building::in_box::holds;
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::read_buildings;
use clap::Parser;
use std::collections::BTreeSet;
use std::path::Path;

/// About 220 x 330 m of Kirchfeld: its borders cut through buildings.
const BOX: &str = "8.3990,49.0530,8.4020,49.0560";

/// The OSM ids of every job in the database at `db`.
async fn queued(db: &Path) -> BTreeSet<String> {
    let pool = citymesh::db::open(db.to_str().unwrap()).await.unwrap();
    sqlx::query_scalar::<_, String>("SELECT osm_id FROM roof_jobs")
        .fetch_all(&pool)
        .await
        .unwrap()
        .into_iter()
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_server_and_the_command_classify_the_same_buildings_of_a_box() {
    let dir = tempfile::tempdir().unwrap();
    let osm = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let imagery = format!(
        "{}/ortho/{{z}}/{{x}}/{{y}}",
        common::imagery::imagery_server().await
    );
    // The server: POST /classify for the box. Its workers may run the jobs; the rows stay.
    let server_db = dir.path().join("server.sqlite");
    let args = common::imagery::classifying_args(&server_db, &osm, &imagery, "ortho");
    let state = citymesh::server::build_state(&args).await.unwrap();
    let app = citymesh::app(state.clone());
    let answer = common::post_json(&app, "/classify", serde_json::json!({"bbox": BOX})).await;
    assert_eq!(answer.status, StatusCode::ACCEPTED, "{}", answer.text());
    let server_counts = answer.json()["counts"].clone();
    state
        .generator
        .roofs
        .shut_down(std::time::Duration::from_secs(60))
        .await;
    // The command, on the same file and box.
    let command_db = dir.path().join("command.sqlite");
    let out = dir.path().join("roofs.geojson");
    let command = ClassifyArgs::parse_from([
        "classify",
        "--osm",
        osm.to_str().unwrap(),
        "--bbox",
        BOX,
        "--imagery-url",
        &imagery,
        "--imagery-id",
        "ortho",
        "--cache-db",
        command_db.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let summary = citymesh::commands::classify::run(&command).await.unwrap();
    let (by_server, by_command) = (queued(&server_db).await, queued(&command_db).await);
    assert_eq!(by_server, by_command, "{server_counts} / {summary}");
    // The untagged buildings (not parts, without parts, at least 12 m²) whose centre the box
    // holds: counted on this Kirchfeld extract (94 more are tagged, 1 is under 12 m²).
    assert_eq!(by_server.len(), 47, "{server_counts}");
    // The old rule of the command (the first node in the box) picks other buildings here: the
    // box's borders cut through some.
    let bbox: GeoBbox = BOX.parse().unwrap();
    let records = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let first_node_only = records
        .iter()
        .filter(|r| {
            let n = &r.outers[0].nodes[0];
            bbox.contains(n.lon, n.lat) != holds(&bbox, r)
        })
        .count();
    assert!(
        first_node_only > 0,
        "the box cuts no building: choose another"
    );
}

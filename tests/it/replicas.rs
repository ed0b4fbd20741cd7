//! Two citymesh processes on one PostgreSQL, as replicas behind a load balancer: one generation
//! per tile across them, data changes seen by both without a restart, and roof jobs shared by
//! their workers, surviving a kill -9 of one. Real processes (the built binary), a real
//! PostgreSQL started here, imagery from a server started here.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use common::postgres::Postgres;
use serde_json::Value;
use std::path::Path;
use std::process::Child;
use std::time::{Duration, Instant};

/// A replica: its process and base URL; killed when dropped.
struct Replica {
    child: Child,
    url: String,
}

impl Drop for Replica {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `citymesh serve` on `database_url` with `extra`; its log is drained.
fn replica(dir: &Path, database_url: &str, extra: &[&str]) -> Replica {
    let mut args = vec!["--database-url", database_url];
    args.extend_from_slice(extra);
    let (child, addr, lines) = common::serve_binary(dir, &args);
    std::thread::spawn(move || lines.for_each(drop));
    Replica {
        child,
        url: format!("http://{addr}"),
    }
}

/// A metric's value from `/metrics` (0 when absent).
async fn metric(http: &reqwest::Client, r: &Replica, name: &str) -> f64 {
    let text = http
        .get(format!("{}/metrics", r.url))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    text.lines()
        .find(|l| l.starts_with(name) && l[name.len()..].starts_with(' '))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0)
}

/// A z16 tile well inside Karlsruhe-Kirchfeld's data tiles.
const TILE: &str = "/tiles/16/34297/22493.glb";

/// The tile's status, bytes, ETag and buildings (their feature rows, read from the bytes: only
/// a generating request's answer has the count in a header).
async fn tile(http: &reqwest::Client, r: &Replica) -> (u16, Vec<u8>, String, usize) {
    let answer = http.get(format!("{}{TILE}", r.url)).send().await.unwrap();
    let status = answer.status().as_u16();
    let etag = answer
        .headers()
        .get("etag")
        .map(|v| v.to_str().unwrap().to_owned())
        .unwrap_or_default();
    let bytes = answer.bytes().await.unwrap().to_vec();
    let buildings = common::decode::feature_rows(&bytes).len();
    (status, bytes, etag, buildings)
}

/// Imports `file` into the shared database with the real `citymesh import`; answers how many
/// data tiles changed.
fn import(database_url: &str, file: &Path) -> u64 {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .args(["import", "--quiet", "--database-url", database_url])
        .arg(file)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // "imported N buildings (S skipped) into T data tiles (C changed; ..."
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    said.split(" changed;")
        .next()
        .and_then(|s| s.rsplit('(').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count of changed data tiles in: {said}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_replicas_generate_a_tile_once_and_see_each_others_data_changes() {
    let pg = Postgres::start();
    let dir = tempfile::tempdir().unwrap();
    let loaded = import(
        &pg.url,
        &common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf"),
    );
    assert!(loaded >= 1);
    let a = replica(dir.path(), &pg.url, &["--classify-workers", "0"]);
    let b = replica(dir.path(), &pg.url, &["--classify-workers", "0"]);
    let http = reqwest::Client::new();

    // 50 concurrent cold requests for one tile, spread over both replicas.
    let answers = futures_util::future::join_all((0..50).map(|i| {
        let (http, r) = (http.clone(), if i % 2 == 0 { &a } else { &b });
        async move { tile(&http, r).await }
    }))
    .await;
    let first = &answers[0];
    assert_eq!(first.0, 200);
    assert!(first.3 > 2, "{} buildings", first.3);
    for answer in &answers {
        assert_eq!(
            (answer.0, &answer.1, &answer.2),
            (200, &first.1, &first.2),
            "every answer has the same bytes and ETag"
        );
    }
    let generations = metric(&http, &a, "citymesh_generations_total").await
        + metric(&http, &b, "citymesh_generations_total").await;
    assert_eq!(generations, 1.0, "one generation over both replicas");

    // Other data over the same area, imported while both run: every other building is gone
    // (and the multipolygons, whose members may be).
    let mut doc: Value =
        serde_json::from_slice(&common::osm_bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
    let mut k = 0;
    doc["elements"].as_array_mut().unwrap().retain(|e| {
        let building = e["type"] == "way" && e["tags"].get("building").is_some();
        k += usize::from(building);
        e["type"] != "relation" && (!building || k % 2 == 0)
    });
    let changed = dir.path().join("changed.json");
    std::fs::write(&changed, serde_json::to_vec(&doc).unwrap()).unwrap();
    let before = first.3;
    let changed_data_tiles = import(&pg.url, &changed);
    assert!(changed_data_tiles >= 1);
    let imported = Instant::now();
    // Both replicas answer the new tile, with no restart (polled every 20 ms, at most 3,000
    // times; how long it took is printed, not asserted).
    let mut seen = [None, None];
    for _ in 0..3_000 {
        if seen.iter().all(Option::is_some) {
            break;
        }
        for (i, r) in [&a, &b].into_iter().enumerate() {
            if seen[i].is_none() {
                let t = tile(&http, r).await;
                if t.2 != first.2 {
                    seen[i] = Some((imported.elapsed(), t));
                }
            }
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let [Some((after_a, ta)), Some((after_b, tb))] = seen else {
        panic!(
            "a replica never served the changed tile: {:?}",
            seen.iter().map(Option::is_some).collect::<Vec<_>>()
        )
    };
    eprintln!("the change reached the replicas after {after_a:?} and {after_b:?}");
    assert!(ta.3 < before, "{} buildings after, {before} before", ta.3);
    assert_eq!((&ta.1, &ta.2), (&tb.1, &tb.2), "the same new tile on both");
    // Health names the shared database; once it is gone, a 503 that says so.
    let health = http.get(format!("{}/health", a.url)).send().await.unwrap();
    assert_eq!(health.status(), 200);
    let health: Value = serde_json::from_slice(&health.bytes().await.unwrap()).unwrap();
    assert_eq!(health["database"]["backend"], "postgres");
    for r in [&a, &b] {
        // One announcement per changed data tile, heard by each replica.
        assert_eq!(
            metric(&http, r, "citymesh_data_change_notifications_total").await,
            changed_data_tiles as f64
        );
    }
    drop(pg);
    let health = http.get(format!("{}/health", b.url)).send().await.unwrap();
    assert_eq!(health.status(), 503);
    let health: Value = serde_json::from_slice(&health.bytes().await.unwrap()).unwrap();
    assert_eq!(health["error"], "database_unreachable", "{health}");
    // Tiles held in memory are still served.
    assert_eq!(tile(&http, &b).await.0, 200);
}

/// The area whose buildings are classified.
const CLASSIFIED: &str = "8.39,49.045,8.41,49.065";

/// A lon/lat ring's area in m², roughly (equirectangular at its first point).
fn rough_area_m2(ring: &[[f64; 2]]) -> f64 {
    let k = 111_320.0 * ring[0][1].to_radians().cos();
    let twice: f64 = (0..ring.len())
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            (a[0] * k) * (b[1] * 111_320.0) - (b[0] * k) * (a[1] * 111_320.0)
        })
        .sum();
    twice.abs() / 2.0
}

/// The ids of `n` of `records` the server queues for `CLASSIFIED`: whose outline's and footprint's centres lie in it, and well over the
/// smallest footprint classified (12 m²).
fn some_buildings(records: &[citymesh_core::osm::BuildingRecord], n: usize) -> Vec<String> {
    let area: citymesh_core::geo::GeoBbox = CLASSIFIED.parse().unwrap();
    let centre_in = |[w, s, e, n]: [f64; 4]| area.contains((w + e) / 2.0, (s + n) / 2.0);
    let in_box: Vec<&citymesh_core::osm::BuildingRecord> = records
        .iter()
        .filter(|r| centre_in(citymesh_core::building::cluster::record_bounds(r)))
        .collect();
    let (jobs, _) =
        citymesh::roofs::jobs::select_buildings(&in_box, citymesh::roofs::jobs::Selection::All);
    let mut ids: Vec<String> = jobs
        .into_iter()
        .filter(|j| {
            centre_in(citymesh::roofs::jobs::ring_bounds(&j.footprint).unwrap())
                && rough_area_m2(&j.footprint) > 30.0
        })
        .map(|j| j.osm_id)
        .collect();
    ids.sort();
    ids.dedup();
    ids.truncate(n);
    ids
}

/// The jobs' states, the predictions and the attempts, read from the shared database.
async fn job_figures(url: &str) -> (Vec<(String, i64)>, i64, i64) {
    let pool = sqlx::postgres::PgPoolOptions::new()
        .max_connections(1)
        .connect(url)
        .await
        .unwrap();
    let states: Vec<(String, i64)> =
        sqlx::query_as("SELECT state, COUNT(*) FROM roof_jobs GROUP BY state ORDER BY state")
            .fetch_all(&pool)
            .await
            .unwrap();
    let (predictions,): (i64,) = sqlx::query_as("SELECT COUNT(*) FROM roof_predictions")
        .fetch_one(&pool)
        .await
        .unwrap();
    let (attempts,): (i64,) =
        sqlx::query_as("SELECT COALESCE(SUM(attempts), 0)::BIGINT FROM roof_jobs")
            .fetch_one(&pool)
            .await
            .unwrap();
    (states, predictions, attempts)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_hundred_roof_jobs_are_shared_by_both_replicas_and_survive_a_kill() {
    let pg = Postgres::start();
    let dir = tempfile::tempdir().unwrap();
    let base = common::imagery::imagery_server().await;
    let grey = format!("{base}/grey/{{z}}/{{x}}/{{y}}.png");
    // Kirchfeld without roof tags: every prediction shapes a roof of `roofs=classified`.
    let mut records =
        citymesh_core::osm::read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings;
    records.iter_mut().for_each(|r| {
        r.tags.remove("roof:shape");
    });
    let osm = dir.path().join("kirchfeld-untagged.json");
    let refs: Vec<&citymesh_core::osm::BuildingRecord> = records.iter().collect();
    std::fs::write(&osm, citymesh_core::osm::write_overpass_json(&refs)).unwrap();
    let args = [
        "--osm",
        osm.to_str().unwrap(),
        "--roof-classifier",
        "--imagery-url",
        &grey,
        "--classify-lease-s",
        "3",
    ];
    let mut a = replica(dir.path(), &pg.url, &args);
    let b = replica(dir.path(), &pg.url, &args);
    let http = reqwest::Client::new();
    let ids = some_buildings(&records, 200);
    assert_eq!(ids.len(), 200);
    let body = serde_json::json!({
        "bbox": CLASSIFIED,
        "osm_ids": ids
    });
    let created = http
        .post(format!("{}/classify", a.url))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let created: Value = serde_json::from_slice(&created).unwrap();
    assert_eq!(created["counts"]["queued"], 200, "{created}");
    let id = created["id"].as_str().unwrap().to_owned();
    let progress = |r: &Replica| {
        let (http, url) = (http.clone(), format!("{}/classify/{id}", r.url));
        async move {
            let body = http.get(url).send().await.unwrap().bytes().await.unwrap();
            serde_json::from_slice::<Value>(&body).unwrap()
        }
    };
    // Let both work, then kill -9 one in the middle of the batch.
    let deadline = Instant::now() + Duration::from_secs(600);
    // Counted as each worker round ends: A's last round, cut short by the kill, is not in it;
    // so the kill waits until A has finished a round as well.
    let claimed_by_a = loop {
        let p = progress(&b).await;
        let by_a = metric(&http, &a, "citymesh_roof_jobs_claimed_total").await;
        if p["jobs"]["done"].as_i64().unwrap() >= 40 && by_a > 0.0 {
            break by_a;
        }
        assert!(Instant::now() < deadline, "{p}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    a.child.kill().unwrap();
    a.child.wait().unwrap();
    let (states, _, _) = job_figures(&pg.url).await;
    eprintln!("killed one replica with {states:?}");
    assert!(
        states.iter().any(|(s, n)| s == "queued" && *n > 0),
        "the batch ended before the kill: {states:?}"
    );
    // The other finishes the batch, the dead one's claims included once their leases run out.
    loop {
        let p = progress(&b).await;
        if p["finished"] == true {
            break;
        }
        assert!(Instant::now() < deadline, "{p}");
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
    let claimed_by_b = metric(&http, &b, "citymesh_roof_jobs_claimed_total").await;
    let (states, predictions, attempts) = job_figures(&pg.url).await;
    eprintln!(
        "claimed by A {claimed_by_a}, by B {claimed_by_b}; {states:?}, {predictions} \
         predictions, {attempts} attempts"
    );
    assert!(
        claimed_by_a > 0.0 && claimed_by_b > 0.0,
        "both replicas worked"
    );
    assert_eq!(states, [("done".to_owned(), 200)]);
    assert_eq!(predictions, 200, "each job done exactly once");
    // Only the jobs A held when killed ran twice (A's claim at that moment, at most 16).
    assert!((200..=216).contains(&attempts), "{attempts} attempts");
    // B's classified roofs use every prediction, A's included (announced through PostgreSQL).
    let stats = http
        .get(format!(
            "{}/scene/stats?bbox={CLASSIFIED}&roofs=classified",
            b.url
        ))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let stats: Value = serde_json::from_slice(&stats).unwrap();
    let figures = &stats["classified_roofs"];
    assert_eq!(
        figures["classified"].as_u64().unwrap() + figures["uncertain"].as_u64().unwrap(),
        200,
        "{figures}"
    );
}

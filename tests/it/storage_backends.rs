//! The stores on both databases: every scenario runs on SQLite and on a real PostgreSQL started
//! by the test, with the same exact answers. Then what only PostgreSQL does, with two processes'
//! worth of pools on one server: one generation per tile, and data changes announced.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use citymesh::cache::{GenerationTurn, TileKey, TileStore};
use citymesh::db::Database;
use citymesh::roofs::imagery::ImageryCache;
use citymesh::source::data_tiles::{DataOrigin, OsmTileStore};
use citymesh_core::geo::TileCoord;
use common::postgres::Postgres;
use std::time::Duration;

/// A SQLite file in `dir`.
async fn sqlite(dir: &tempfile::TempDir) -> Database {
    Database::Sqlite(
        citymesh::db::open(dir.path().join("t.sqlite").to_str().unwrap())
            .await
            .unwrap(),
    )
}

async fn postgres(pg: &Postgres) -> Database {
    Database::Postgres(citymesh::db::open_postgres(&pg.url, 8).await.unwrap())
}

/// Runs `scenario` on SQLite and on PostgreSQL; answers both transcripts.
macro_rules! on_both {
    ($scenario:ident) => {{
        let dir = tempfile::tempdir().unwrap();
        let on_sqlite = $scenario(sqlite(&dir).await).await;
        let pg = Postgres::start();
        let on_postgres = $scenario(postgres(&pg).await).await;
        (on_sqlite, on_postgres)
    }};
}

/// Tile cost on both backends: bytes and the estimated row overhead.
const COST: u64 = 1_000 + 2_560;

fn key(i: u32) -> TileKey {
    TileKey::xyz(TileCoord::new(16, 34_290 + i, 22_493).unwrap())
}

async fn tile_scenario(db: Database) -> Vec<String> {
    // Writes and uses are stamped in milliseconds: the test moves the clock between them.
    let clock = citymesh::clock::Clock::manual_from_now();
    let store = TileStore::open(&db, 40 * COST, "test")
        .await
        .unwrap()
        .with_clock(clock.clone());
    let tick = || clock.advance(Duration::from_millis(2));
    let get = |i: u32, v: &'static str| {
        let store = store.clone();
        async move { store.get(&key(i), v).await.unwrap() }
    };
    let mut seen = Vec::new();
    store
        .put(&key(0), "v1", &[1; 1_000], "a", None)
        .await
        .unwrap();
    let got = get(0, "v1").await.unwrap();
    seen.push(format!("{} {} {}", got.bytes.len(), got.bytes[0], got.etag));
    seen.push(format!("{}", get(0, "v2").await.is_none()));
    store
        .put(&key(0), "v1", &[2; 1_000], "b", None)
        .await
        .unwrap();
    let got = get(0, "v1").await.unwrap();
    seen.push(format!(
        "{} {} {}",
        got.bytes[0],
        got.etag,
        store.used_bytes() == COST
    ));
    let area = key(0).tile.bounds();
    seen.push(format!(
        "{}",
        store.delete_overlapping(&area).await.unwrap()
    ));
    seen.push(format!("{}", get(0, "v1").await.is_none()));
    // Past the bound of 40 tiles, the least recently used go first, 32 at a time: 1 and 2 were
    // read again, so 3 to 34 go.
    for i in 1..=40 {
        store
            .put(&key(i), "v1", &[3; 1_000], "c", None)
            .await
            .unwrap();
        tick();
    }
    get(1, "v1").await.unwrap();
    tick();
    get(2, "v1").await.unwrap();
    tick();
    store
        .put(&key(41), "v1", &[4; 1_000], "d", None)
        .await
        .unwrap();
    let mut kept = Vec::new();
    for i in 1..=41 {
        if get(i, "v1").await.is_some() {
            kept.push(i);
        }
    }
    seen.push(format!("{kept:?} {}", store.used_bytes() <= 40 * COST));
    seen
}

#[tokio::test]
async fn generated_tiles_are_stored_replaced_deleted_and_evicted_alike() {
    let (on_sqlite, on_postgres) = on_both!(tile_scenario);
    let expected = [
        "1000 1 a",
        "true",
        "2 b true",
        "1",
        "true",
        "[1, 2, 35, 36, 37, 38, 39, 40, 41] true",
    ];
    assert_eq!(on_sqlite, expected);
    assert_eq!(on_postgres, expected);
}

/// A data tile's summary of Karlsruhe-Kirchfeld, made from its buildings and the DEM.
fn kirchfeld_summary() -> citymesh_core::tiles3d::TileSummary {
    let t = TileCoord::new(14, 8574, 5623).unwrap();
    let set = citymesh_core::building::set::BuildingSet::new(
        citymesh_core::osm::read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    let dem = citymesh::dem::DemStore::open(&common::dem_dir(), 64 << 20);
    let model = dem.lookup(&t.bounds().grown_by_degrees(0.01)).model;
    citymesh_core::tiles3d::TileSummary::of_data_tile(
        t,
        &set,
        &model,
        citymesh_core::building::RoofMethod::default(),
    )
    .unwrap()
}

async fn summary_scenario(db: Database) -> Vec<String> {
    let store = TileStore::open(&db, u64::MAX, "test").await.unwrap();
    let summary = kirchfeld_summary();
    let t = summary.tile;
    let parent = TileCoord::new(13, t.x / 2, t.y / 2).unwrap();
    let mut seen = Vec::new();
    store
        .put_summaries(&[(t, Some(&summary)), (parent, Some(&summary))], "v1")
        .await
        .unwrap();
    // Read back exactly, for its data version only.
    seen.push(format!(
        "{}",
        store.summary(t, "v1").await.unwrap() == Some(summary.clone())
    ));
    seen.push(format!(
        "{}",
        store.summary(t, "v2").await.unwrap().is_none()
    ));
    // A row naming another tile is never taken for this one's.
    seen.push(format!(
        "{}",
        store.summary(parent, "v1").await.unwrap().is_none()
    ));
    // Made again for another version: the row is replaced.
    store
        .put_summaries(&[(t, Some(&summary))], "v2")
        .await
        .unwrap();
    seen.push(format!(
        "{} {}",
        store.summary(t, "v1").await.unwrap().is_none(),
        store.summary(t, "v2").await.unwrap().is_some()
    ));
    // Data changed over a corner of the tile: its summary and its parent's go with the tiles.
    let b = t.bounds();
    let corner = citymesh_core::geo::GeoBbox::new(
        b.min_lon(),
        b.min_lat(),
        b.min_lon() + 1e-4,
        b.min_lat() + 1e-4,
    )
    .unwrap();
    store.delete_overlapping(&corner).await.unwrap();
    seen.push(format!(
        "{}",
        store.summary(t, "v2").await.unwrap().is_none()
    ));
    // A tile without buildings any more: its row goes.
    store
        .put_summaries(&[(t, Some(&summary))], "v3")
        .await
        .unwrap();
    store.put_summaries(&[(t, None)], "v3").await.unwrap();
    seen.push(format!(
        "{}",
        store.summary(t, "v3").await.unwrap().is_none()
    ));
    seen
}

#[tokio::test]
async fn tile_summaries_are_kept_per_data_version_and_dropped_with_changed_data_alike() {
    let (on_sqlite, on_postgres) = on_both!(summary_scenario);
    let expected = ["true", "true", "true", "true true", "true", "true"];
    assert_eq!(on_sqlite, expected);
    assert_eq!(on_postgres, expected);
}

async fn data_tile_scenario(db: Database) -> Vec<String> {
    // Room for two 1,000-byte Overpass tiles; imported ones never count or leave.
    // Uses and fetches are stamped in whole seconds: the test moves the clock a second on.
    let clock = citymesh::clock::Clock::manual_from_now();
    let store = OsmTileStore::bounded(db, 2_500).with_clock(clock.clone());
    let t = |x| TileCoord::new(14, x, 5_621).unwrap();
    let mut seen = Vec::new();
    seen.push(format!(
        "{}",
        store
            .put(&t(0), &[1; 1_000], DataOrigin::Overpass)
            .await
            .unwrap()
    ));
    // The same body again changes nothing; another does.
    seen.push(format!(
        "{}",
        store
            .put(&t(0), &[1; 1_000], DataOrigin::Overpass)
            .await
            .unwrap()
    ));
    seen.push(format!(
        "{}",
        store
            .put(&t(0), &[2; 1_000], DataOrigin::Overpass)
            .await
            .unwrap()
    ));
    store
        .put(&t(9), &[9; 5_000], DataOrigin::Import)
        .await
        .unwrap();
    let got = store.get(&t(0)).await.unwrap().unwrap();
    seen.push(format!(
        "{} {} {:?} {}",
        got.body[0],
        got.hash,
        got.origin,
        got.fetched_at > 1_700_000_000
    ));
    clock.advance(Duration::from_millis(1_100));
    store
        .put(&t(1), &[3; 1_000], DataOrigin::Overpass)
        .await
        .unwrap();
    clock.advance(Duration::from_millis(1_100));
    // Tile 0 is read again: tile 1 is now the least recently used, and leaves when 2 comes.
    store.get(&t(0)).await.unwrap().unwrap();
    clock.advance(Duration::from_millis(1_100));
    store
        .put(&t(2), &[4; 1_000], DataOrigin::Overpass)
        .await
        .unwrap();
    let mut kept = Vec::new();
    for x in 0..10 {
        if store.get(&t(x)).await.unwrap().is_some() {
            kept.push(x);
        }
    }
    seen.push(format!(
        "{kept:?} {} {}",
        store.overpass_bytes().await.unwrap(),
        store.count().await.unwrap()
    ));
    seen
}

#[tokio::test]
async fn data_tiles_are_stored_compared_and_evicted_alike() {
    let (on_sqlite, on_postgres) = on_both!(data_tile_scenario);
    let hash = citymesh::source::data_tiles::content_hash(&[2; 1_000]);
    let expected = [
        "true".to_owned(),
        "false".to_owned(),
        "true".to_owned(),
        format!("2 {hash} Overpass true"),
        "[0, 2, 9] 2000 3".to_owned(),
    ];
    assert_eq!(on_sqlite, expected);
    assert_eq!(on_postgres, expected);
}

async fn imagery_scenario(db: Database) -> Vec<String> {
    // Fetches and uses are stamped in milliseconds: the test moves the clock between them.
    let clock = citymesh::clock::Clock::manual_from_now();
    let tick = || clock.advance(Duration::from_millis(2));
    let cache = ImageryCache::new(db.clone(), Duration::from_secs(3600), 10_000)
        .await
        .unwrap()
        .with_clock(clock.clone());
    let t = |x| TileCoord::new(18, x, 7).unwrap();
    for x in 0..4 {
        cache.put("a", t(x), &[x as u8; 3000]).await.unwrap();
        // Tile 0 is used again before each put: it stays.
        assert!(cache.get("a", t(0)).await.unwrap().is_some());
        tick();
    }
    let mut seen = Vec::new();
    for x in 0..4 {
        let got = cache.get("a", t(x)).await.unwrap();
        seen.push(format!("{x}: {:?}", got.map(|b| (b.len(), b[0]))));
    }
    // Another imagery never sees these tiles; past the time to live, a tile is not served.
    seen.push(format!("{:?}", cache.get("b", t(0)).await.unwrap()));
    let short = ImageryCache::new(db, Duration::from_millis(0), 10_000)
        .await
        .unwrap()
        .with_clock(clock.clone());
    tick();
    seen.push(format!("{:?}", short.get("a", t(0)).await.unwrap()));
    seen
}

#[tokio::test]
async fn imagery_tiles_expire_and_the_least_recently_used_go_first_alike() {
    let (on_sqlite, on_postgres) = on_both!(imagery_scenario);
    // 12,000 bytes went in, over the 10,000 bound: the least recently used (tile 1) left.
    let expected = [
        "0: Some((3000, 0))",
        "1: None",
        "2: Some((3000, 2))",
        "3: Some((3000, 3))",
        "None",
        "None",
    ];
    assert_eq!(on_sqlite, expected);
    assert_eq!(on_postgres, expected);
}

/// Two replicas' stores on one PostgreSQL (separate pools, as separate processes have).
async fn two_replicas(pg: &Postgres) -> (TileStore, TileStore) {
    let a = Database::Postgres(citymesh::db::open_postgres(&pg.url, 4).await.unwrap());
    let b = Database::Postgres(citymesh::db::open_postgres(&pg.url, 4).await.unwrap());
    (
        TileStore::open(&a, u64::MAX, "a").await.unwrap(),
        TileStore::open(&b, u64::MAX, "b").await.unwrap(),
    )
}

/// Returns once a session of `pg` waits for an advisory lock (polled in `pg_locks`).
async fn lock_awaited(pg: &Postgres) {
    let pool = citymesh::db::open_postgres(&pg.url, 1).await.unwrap();
    for _ in 0..6_000 {
        let waiting: i64 = sqlx::query_scalar(
            "SELECT COUNT(*) FROM pg_locks WHERE locktype = 'advisory' AND NOT granted",
        )
        .fetch_one(&pool)
        .await
        .unwrap();
        if waiting > 0 {
            return;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("no session waited for the advisory lock");
}

#[tokio::test]
async fn a_replica_missing_a_tile_another_generates_waits_for_its_row() {
    let pg = Postgres::start();
    let (a, b) = two_replicas(&pg).await;
    let k = key(7);
    let GenerationTurn::Generate {
        lock: Some(lock),
        waited: false,
        timed_out: false,
    } = a.turn(&k, "v1", Duration::from_secs(5)).await.unwrap()
    else {
        panic!("the first to miss generates, holding the lock");
    };
    // B misses while A generates: it waits for A's row instead of generating.
    let waiting = tokio::spawn({
        let b = b.clone();
        async move { b.turn(&k, "v1", Duration::from_secs(60)).await.unwrap() }
    });
    lock_awaited(&pg).await;
    assert!(!waiting.is_finished(), "B must wait while A holds the lock");
    a.put(&k, "v1", b"the tile", "\"e1\"", Some(lock))
        .await
        .unwrap();
    match waiting.await.unwrap() {
        GenerationTurn::Stored { tile, waited } => {
            assert!(waited);
            assert_eq!(
                (&tile.bytes[..], tile.etag.as_str()),
                (&b"the tile"[..], "\"e1\"")
            );
        }
        GenerationTurn::Generate { .. } => panic!("B generated a tile A had written"),
    }
    // Once written, the turn answers the row at once.
    assert!(matches!(
        b.turn(&k, "v1", Duration::from_secs(5)).await.unwrap(),
        GenerationTurn::Stored { waited: false, .. }
    ));
}

#[tokio::test]
async fn a_replica_whose_wait_runs_out_or_whose_holder_gives_up_generates_itself() {
    let pg = Postgres::start();
    let (a, b) = two_replicas(&pg).await;
    let k = key(8);
    let GenerationTurn::Generate {
        lock: Some(lock), ..
    } = a.turn(&k, "v1", Duration::from_secs(5)).await.unwrap()
    else {
        panic!("the first to miss generates");
    };
    // A takes too long: B's 100 ms wait runs out and B generates, without the lock.
    assert!(matches!(
        b.turn(&k, "v1", Duration::from_millis(100)).await.unwrap(),
        GenerationTurn::Generate {
            lock: None,
            waited: true,
            timed_out: true
        }
    ));
    // A gives up (its generation failed): a waiting B gets the lock and generates.
    let waiting = tokio::spawn({
        let b = b.clone();
        async move { b.turn(&k, "v1", Duration::from_secs(60)).await.unwrap() }
    });
    lock_awaited(&pg).await;
    drop(lock);
    assert!(matches!(
        waiting.await.unwrap(),
        GenerationTurn::Generate {
            lock: Some(_),
            waited: true,
            timed_out: false
        }
    ));
}

#[tokio::test]
async fn deleting_tiles_over_an_area_tells_every_listening_replica_in_the_same_transaction() {
    let pg = Postgres::start();
    let (a, b) = two_replicas(&pg).await;
    assert_eq!(b.backend(), "postgres");
    let pool = citymesh::db::open_postgres(&pg.url, 2).await.unwrap();
    let mut listener = sqlx::postgres::PgListener::connect_with(&pool)
        .await
        .unwrap();
    listener
        .listen(citymesh::cache::DATA_CHANGED_CHANNEL)
        .await
        .unwrap();
    a.put(&key(3), "v1", b"x", "\"x\"", None).await.unwrap();
    let area = key(3).tile.bounds();
    assert_eq!(a.delete_overlapping(&area).await.unwrap(), 1);
    let note = tokio::time::timeout(Duration::from_secs(5), listener.recv())
        .await
        .unwrap()
        .unwrap();
    let note = citymesh::cache::DataChangedNote::parse(note.payload()).unwrap();
    assert_eq!((note.sender.as_str(), note.area), ("a", area));
    // The tile was gone for B by then.
    assert!(b.get(&key(3), "v1").await.unwrap().is_none());
}

/// Round 3, item 6: tile misses waiting on a slow Overpass hold no database connection (they
/// gather their data before taking their generation turn), so `/health` stays 200 on
/// PostgreSQL while they wait, and no connection sits idle in a transaction.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn misses_waiting_on_upstream_hold_no_database_connection() {
    use axum::body::Body;
    use axum::http::{Request, StatusCode};
    use std::sync::Arc;
    use tower::ServiceExt as _;
    // An Overpass that answers only when the test says so, and tells when it is asked.
    #[derive(Clone)]
    struct Stub {
        asked: Arc<tokio::sync::watch::Sender<usize>>,
        release: Arc<tokio::sync::Semaphore>,
    }
    async fn answer(axum::extract::State(stub): axum::extract::State<Stub>) -> &'static str {
        stub.asked.send_modify(|n| *n += 1);
        let _ = stub
            .release
            .acquire()
            .await
            .map(tokio::sync::SemaphorePermit::forget);
        r#"{"elements": []}"#
    }
    let (asked, mut asked_rx) = tokio::sync::watch::channel(0usize);
    let stub = Stub {
        asked: Arc::new(asked),
        release: Arc::new(tokio::sync::Semaphore::new(0)),
    };
    let upstream = axum::Router::new()
        .route("/api/interpreter", axum::routing::post(answer))
        .with_state(stub.clone());
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let overpass = format!("http://{}/api/interpreter", listener.local_addr().unwrap());
    tokio::spawn(async move { axum::serve(listener, upstream).await.unwrap() });

    let pg = Postgres::start();
    let dir = tempfile::tempdir().unwrap();
    let app = common::app_with(
        &common::dem_dir(),
        &dir.path().join("c.sqlite"),
        &[
            "--database-url",
            &pg.url,
            "--database-max-connections",
            "4",
            "--overpass-url",
            &overpass,
            "--overpass-retries",
            "0",
        ],
    )
    .await;
    // Eight misses in one data tile: all wait for the one Overpass answer.
    let misses: Vec<_> = (0..8)
        .map(|i| {
            let app = app.clone();
            tokio::spawn(async move {
                let uri = format!("/tiles/16/{}/22493.glb", 34_290 + (i % 4));
                let uri = if i >= 4 {
                    format!("{uri}?encoding=meshopt")
                } else {
                    uri
                };
                app.oneshot(Request::get(uri).body(Body::empty()).unwrap())
                    .await
                    .unwrap()
                    .status()
            })
        })
        .collect();
    asked_rx.wait_for(|n| *n >= 1).await.unwrap();
    let watcher = citymesh::db::open_postgres(&pg.url, 1).await.unwrap();
    let (in_transaction,): (i64,) = sqlx::query_as(
        "SELECT COUNT(*) FROM pg_stat_activity WHERE state LIKE 'idle in transaction%'",
    )
    .fetch_one(&watcher)
    .await
    .unwrap();
    assert_eq!(in_transaction, 0, "connections held while Overpass answers");
    let health = common::get(&app, "/health").await;
    assert_eq!(health.status, StatusCode::OK, "{}", health.text());
    stub.release.add_permits(1_000);
    for miss in misses {
        assert_eq!(miss.await.unwrap(), StatusCode::OK);
    }
}

//! Serving with an upstream: a stub Overpass server started here on 127.0.0.1 answers with the
//! real Karlsruhe-Kirchfeld data (filtered to the asked box, as Overpass does) and counts its
//! requests. Single flight under load, no upstream after a restart, every kind of upstream
//! failure, import then offline, and adjacent tiles that hold each building once and share their
//! ground edges.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{LocalFrame, TileCoord};
use citymesh_core::osm::read_buildings;
use common::{app_with, assert_valid_glb, data_dir, dem_dir, get, osm_bytes};
use serde_json::Value;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// How the stub answers.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    Normal,
    ServerError,
    TooManyRequests,
    Hang,
    Truncated,
    /// Newer data: every other building way of the normal answer is gone.
    Thinner,
    /// Newer data: the buildings with an even id lost their `roof:shape`.
    FewerRoofTags,
}

pub(crate) struct Stub {
    mode: Mutex<Mode>,
    requests: AtomicUsize,
    ways: Vec<Value>,
    relations: Vec<Value>,
    nodes: HashMap<i64, Value>,
}

impl Stub {
    pub(crate) fn new() -> Arc<Self> {
        let doc: Value =
            serde_json::from_slice(&osm_bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
        let mut ways = Vec::new();
        let mut relations = Vec::new();
        let mut nodes = HashMap::new();
        for e in doc["elements"].as_array().unwrap() {
            match e["type"].as_str() {
                Some("node") => {
                    nodes.insert(e["id"].as_i64().unwrap(), e.clone());
                }
                Some("way") => ways.push(e.clone()),
                Some("relation") => relations.push(e.clone()),
                _ => {}
            }
        }
        Arc::new(Stub {
            mode: Mutex::new(Mode::Normal),
            requests: AtomicUsize::new(0),
            ways,
            relations,
            nodes,
        })
    }

    fn set(&self, mode: Mode) {
        *self.mode.lock().unwrap() = mode;
    }

    pub(crate) fn count(&self) -> usize {
        self.requests.load(Ordering::SeqCst)
    }

    /// What Overpass answers for the buildings of (s, w, n, e): the building ways and relations
    /// with a node in the box, their member ways, and all their nodes.
    fn answer(&self, [s, w, n, e]: [f64; 4]) -> Vec<u8> {
        let inside = |id: &Value| {
            self.nodes.get(&id.as_i64().unwrap()).is_some_and(|node| {
                let (lat, lon) = (node["lat"].as_f64().unwrap(), node["lon"].as_f64().unwrap());
                lat >= s && lat <= n && lon >= w && lon <= e
            })
        };
        let way_by_id: HashMap<i64, &Value> = self
            .ways
            .iter()
            .map(|w| (w["id"].as_i64().unwrap(), w))
            .collect();
        let is_building =
            |t: &Value| t.get("building").is_some() || t.get("building:part").is_some();
        let mut out: Vec<Value> = Vec::new();
        // Sorted sets: the same query gets the same answer, byte for byte, and Thinner always
        // drops the same buildings.
        let mut way_ids = BTreeSet::new();
        for way in &self.ways {
            if is_building(&way["tags"]) && way["nodes"].as_array().unwrap().iter().any(inside) {
                way_ids.insert(way["id"].as_i64().unwrap());
            }
        }
        for rel in &self.relations {
            let members: Vec<i64> = rel["members"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|m| m["type"] == "way")
                .map(|m| m["ref"].as_i64().unwrap())
                .collect();
            let hit = members.iter().any(|id| {
                way_by_id
                    .get(id)
                    .is_some_and(|w| w["nodes"].as_array().unwrap().iter().any(inside))
            });
            if hit {
                out.push(rel.clone());
                way_ids.extend(members);
            }
        }
        let mut node_ids = BTreeSet::new();
        for id in &way_ids {
            if let Some(w) = way_by_id.get(id) {
                out.push((*w).clone());
                node_ids.extend(
                    w["nodes"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|n| n.as_i64().unwrap()),
                );
            }
        }
        out.extend(node_ids.iter().filter_map(|id| self.nodes.get(id).cloned()));
        serde_json::to_vec(&serde_json::json!({"version": 0.6, "elements": out})).unwrap()
    }
}

/// The box of an Overpass query: the first "(s,w,n,e)".
fn query_box(query: &str) -> [f64; 4] {
    for part in query.split('(').skip(1) {
        let inner = part.split(')').next().unwrap_or_default();
        let v: Vec<f64> = inner
            .split(',')
            .filter_map(|x| x.trim().parse().ok())
            .collect();
        if v.len() == 4 {
            return [v[0], v[1], v[2], v[3]];
        }
    }
    panic!("no box in the query: {query}")
}

async fn interpreter(
    axum::extract::State(stub): axum::extract::State<Arc<Stub>>,
    axum::Form(form): axum::Form<HashMap<String, String>>,
) -> axum::response::Response {
    use axum::response::IntoResponse;
    stub.requests.fetch_add(1, Ordering::SeqCst);
    let mode = *stub.mode.lock().unwrap();
    let query = form.get("data").cloned().unwrap_or_default();
    match mode {
        Mode::Normal => stub.answer(query_box(&query)).into_response(),
        Mode::ServerError => (StatusCode::INTERNAL_SERVER_ERROR, "boom").into_response(),
        Mode::TooManyRequests => (
            StatusCode::TOO_MANY_REQUESTS,
            [(axum::http::header::RETRY_AFTER, "1")],
            "slow down",
        )
            .into_response(),
        Mode::Hang => {
            tokio::time::sleep(std::time::Duration::from_secs(10)).await;
            stub.answer(query_box(&query)).into_response()
        }
        Mode::Truncated => {
            let full = stub.answer(query_box(&query));
            full[..full.len() / 2].to_vec().into_response()
        }
        Mode::Thinner => {
            let mut doc: Value = serde_json::from_slice(&stub.answer(query_box(&query))).unwrap();
            let mut k = 0;
            doc["elements"].as_array_mut().unwrap().retain(|e| {
                let building = e["type"] == "way" && e["tags"].get("building").is_some();
                k += usize::from(building);
                !building || k % 2 == 0
            });
            // A consistent answer: relations whose member ways are gone go too.
            let ways: HashSet<i64> = doc["elements"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|e| e["type"] == "way")
                .map(|e| e["id"].as_i64().unwrap())
                .collect();
            doc["elements"].as_array_mut().unwrap().retain(|e| {
                e["type"] != "relation"
                    || e["members"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .all(|m| m["type"] != "way" || ways.contains(&m["ref"].as_i64().unwrap()))
            });
            serde_json::to_vec(&doc).unwrap().into_response()
        }
        Mode::FewerRoofTags => {
            let mut doc: Value = serde_json::from_slice(&stub.answer(query_box(&query))).unwrap();
            for e in doc["elements"].as_array_mut().unwrap() {
                if e["id"].as_i64().unwrap_or(1) % 2 == 0
                    && let Some(tags) = e.get_mut("tags").and_then(Value::as_object_mut)
                {
                    tags.remove("roof:shape");
                }
            }
            serde_json::to_vec(&doc).unwrap().into_response()
        }
    }
}

/// Starts the stub on a free port; returns its interpreter URL.
pub(crate) async fn start_stub(stub: Arc<Stub>) -> String {
    let app = axum::Router::new()
        .route("/api/interpreter", axum::routing::post(interpreter))
        .with_state(stub);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    format!("http://{addr}/api/interpreter")
}

/// An app over the stub (no retries), with one more flag and its value.
async fn stub_app(db: &std::path::Path, url: &str, flag: [&str; 2]) -> axum::Router {
    let args = [
        "--overpass-url",
        url,
        "--overpass-retries",
        "0",
        flag[0],
        flag[1],
    ];
    app_with(&dem_dir(), db, &args).await
}

async fn online_app(db: &std::path::Path, url: &str) -> axum::Router {
    stub_app(db, url, ["--overpass-timeout-s", "0.5"]).await
}

/// An app over the stub whose data goes stale after an hour, and the clock its data is stamped
/// with: the test moves it past the hour.
async fn stale_soon_app(db: &std::path::Path, url: &str) -> (axum::Router, citymesh::clock::Clock) {
    let clock = citymesh::clock::Clock::manual_from_now();
    let args = [
        "--overpass-url",
        url,
        "--overpass-retries",
        "0",
        "--osm-ttl-hours",
        "1",
    ];
    let app = common::app_with_clock(&dem_dir(), db, &args, clock.clone()).await;
    (app, clock)
}

/// An hour and a second: past the data's time to live.
const PAST_THE_TTL: std::time::Duration = std::time::Duration::from_secs(3_601);

/// A z16 tile well inside data tile 14/8574/5623, over Karlsruhe-Kirchfeld.
const TILE: &str = "/tiles/16/34297/22493.glb";

fn metric(text: &str, name: &str) -> f64 {
    text.lines()
        .find(|l| l.starts_with(name) && l[name.len()..].starts_with(' '))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0)
}

async fn stored_data_tiles(db: &std::path::Path) -> i64 {
    let pool = citymesh::db::open(db.to_str().unwrap()).await.unwrap();
    citymesh::source::data_tiles::OsmTileStore::new(citymesh::db::Database::Sqlite(pool))
        .count()
        .await
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_hundred_requests_for_a_cold_tile_make_one_upstream_request_and_one_generation() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let app = online_app(&db.path().join("c.sqlite"), &url).await;
    let tasks: Vec<_> = (0..100)
        .map(|_| {
            let app = app.clone();
            tokio::spawn(async move { get(&app, TILE).await })
        })
        .collect();
    let answers = futures_util::future::join_all(tasks).await;
    let first = &answers[0].as_ref().unwrap().body;
    for a in &answers {
        let a = a.as_ref().unwrap();
        assert_eq!(a.status, StatusCode::OK);
        assert_eq!(&a.body, first);
    }
    assert_eq!(stub.count(), 1);
    let metrics = String::from_utf8(get(&app, "/metrics").await.body).unwrap();
    assert_eq!(metric(&metrics, "citymesh_generations_total"), 1.0);
    assert_eq!(
        metric(&metrics, "citymesh_upstream_requests_total{result=\"ok\"}"),
        1.0
    );
    assert_valid_glb(first);
    let t = get(&app, TILE).await;
    assert_eq!(t.header("x-citymesh-cache"), "hit");
    let n: usize = t.header("content-length").parse().unwrap();
    assert_eq!(n, first.len());
}

#[tokio::test]
async fn after_a_restart_stored_data_is_not_asked_for_again() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("c.sqlite");
    let first = get(&online_app(&file, &url).await, TILE).await;
    assert_eq!(first.status, StatusCode::OK);
    assert_eq!(first.header("x-citymesh-osm"), "stored");
    let buildings: usize = first.header("x-citymesh-buildings").parse().unwrap();
    assert!(buildings > 0);
    assert_eq!(buildings, building_ids(&first.body).len());
    assert_eq!(stub.count(), 1);
    // A new server on the same database: the tile from SQLite, and a neighbour tile of the same
    // data tile generated from the stored data, with no upstream request at all.
    common::settle_writes().await;
    let app = online_app(&file, &url).await;
    let again = get(&app, TILE).await;
    assert_eq!(again.header("x-citymesh-cache"), "sqlite");
    assert_eq!(again.body, first.body);
    let neighbour = get(&app, "/tiles/16/34297/22494.glb").await;
    assert_eq!(neighbour.status, StatusCode::OK);
    assert_eq!(neighbour.header("x-citymesh-cache"), "miss");
    assert_eq!(stub.count(), 1);
}

#[tokio::test]
async fn upstream_failures_answer_clearly_store_nothing_and_recover() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("c.sqlite");
    // The upstream's pauses are measured by this clock: the test moves it past a Retry-After.
    let clock = citymesh::clock::Clock::manual_from_now();
    let args = [
        "--overpass-url",
        &url,
        "--overpass-retries",
        "0",
        "--overpass-timeout-s",
        "0.5",
    ];
    let app = common::app_with_clock(&dem_dir(), &file, &args, clock.clone()).await;
    for (mode, status, code, retry_after) in [
        (
            Mode::ServerError,
            StatusCode::BAD_GATEWAY,
            "upstream_failed",
            "30",
        ),
        (
            Mode::Hang,
            StatusCode::GATEWAY_TIMEOUT,
            "upstream_timeout",
            "30",
        ),
        (
            Mode::Truncated,
            StatusCode::BAD_GATEWAY,
            "upstream_failed",
            "30",
        ),
        // Last: after a 429 no call is made until its Retry-After has passed.
        (
            Mode::TooManyRequests,
            StatusCode::SERVICE_UNAVAILABLE,
            "upstream_busy",
            "1",
        ),
    ] {
        stub.set(mode);
        let a = get(&app, TILE).await;
        assert_eq!(a.status, status, "{mode:?}");
        assert_eq!(a.json()["error"], code, "{mode:?}");
        assert_eq!(a.header("retry-after"), retry_after, "{mode:?}");
        assert_eq!(stored_data_tiles(&file).await, 0, "{mode:?} stored data");
    }
    // The stub counted one request per failure: nothing was cached as an answer.
    assert_eq!(stub.count(), 4);
    stub.set(Mode::Normal);
    // Within the 429's delay: answered at once, without a call.
    let held = get(&app, TILE).await;
    assert_eq!(held.status, StatusCode::SERVICE_UNAVAILABLE);
    assert_eq!(held.json()["error"], "upstream_held_back");
    assert_eq!(stub.count(), 4);
    // Past it, the data comes.
    clock.advance(std::time::Duration::from_millis(1100));
    let a = get(&app, TILE).await;
    assert_eq!(a.status, StatusCode::OK);
    assert_eq!(stored_data_tiles(&file).await, 1);
    let metrics = String::from_utf8(get(&app, "/metrics").await.body).unwrap();
    assert_eq!(
        metric(
            &metrics,
            "citymesh_upstream_requests_total{result=\"bad_response\"}"
        ),
        2.0
    );
    assert_eq!(
        metric(
            &metrics,
            "citymesh_upstream_requests_total{result=\"timeout\"}"
        ),
        1.0
    );
    assert_eq!(
        metric(
            &metrics,
            "citymesh_upstream_requests_total{result=\"busy\"}"
        ),
        1.0
    );
}

#[tokio::test]
async fn stale_data_is_served_while_a_refresh_runs_and_a_change_invalidates_its_tiles() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let (app, clock) = stale_soon_app(&db.path().join("c.sqlite"), &url).await;
    let a = get(&app, TILE).await;
    let before: usize = a.header("x-citymesh-buildings").parse().unwrap();
    assert_eq!(stub.count(), 1);
    stub.set(Mode::Thinner);
    assert!(clock.advance(PAST_THE_TTL));
    // A new tile of the same data tile: generated from the stale data, and a refresh starts.
    let b = get(&app, "/tiles/16/34297/22494.glb").await;
    assert_eq!(b.header("x-citymesh-cache"), "miss");
    let mut waited = 0;
    while stub.count() < 2 || get(&app, TILE).await.header("x-citymesh-cache") != "miss" {
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        waited += 1;
        assert!(waited < 600, "no refresh after 30 s");
    }
    assert_eq!(stub.count(), 2);
    // The refresh changed the data tile: its tiles were dropped and are generated anew.
    let after_a = get(&app, TILE).await;
    assert_eq!(after_a.header("x-citymesh-cache"), "hit");
    let after: usize = building_ids(&after_a.body).len();
    assert!(after < before, "{after} buildings after, {before} before");
    assert_eq!(
        get(&app, "/tiles/16/34297/22494.glb")
            .await
            .header("x-citymesh-cache"),
        "miss"
    );
}

/// The prior of the data tile holding `TILE`, as `/scene/stats?roofs=inferred` reports it:
/// its identity and tagged buildings.
async fn tile_prior(app: &axum::Router) -> (String, u64) {
    let bbox = TileCoord::new(16, 34297, 22493).unwrap().bounds();
    let stats = get(app, &format!("/scene/stats?bbox={bbox}&roofs=inferred"))
        .await
        .json();
    let prior = stats["inferred_roofs"]["priors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["scope"] == "14/8574/5623")
        .unwrap()
        .clone();
    (
        prior["identity"].as_str().unwrap().to_owned(),
        prior["tagged"].as_u64().unwrap(),
    )
}

#[tokio::test]
async fn a_refresh_that_changes_roof_tags_changes_the_prior_and_the_inferred_tiles() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let (app, clock) = stale_soon_app(&db.path().join("c.sqlite"), &url).await;
    let uri = format!("{TILE}?roofs=inferred");
    let before = get(&app, &uri).await;
    assert_eq!(before.status, StatusCode::OK);
    let inferred: usize = before
        .header("x-citymesh-roofs")
        .strip_prefix("inferred, ")
        .unwrap()
        .parse()
        .unwrap();
    assert!(inferred > 0, "{}", before.header("x-citymesh-roofs"));
    let (identity, tagged) = tile_prior(&app).await;
    assert_eq!(tagged, 35);

    // Mappers removed half the roof tags; the data goes stale and a request starts a refresh.
    stub.set(Mode::FewerRoofTags);
    assert!(clock.advance(PAST_THE_TTL));
    let _ = get(&app, "/tiles/16/34297/22494.glb").await;
    let mut waited = 0;
    let (new_identity, new_tagged) = loop {
        let now = tile_prior(&app).await;
        if now.0 != identity {
            break now;
        }
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        waited += 1;
        assert!(waited < 600, "the prior did not change after 30 s");
    };
    assert_ne!(new_identity, identity);
    // 35 tagged less those with an even id: under 30, so the prior abstains.
    assert!(new_tagged < 30, "{new_tagged}");
    let after = get(&app, &uri).await;
    assert_ne!(after.header("etag"), before.header("etag"));
    assert_eq!(after.header("x-citymesh-roofs"), "inferred, 0");
}

#[tokio::test]
async fn an_import_that_changes_data_drops_exactly_the_tiles_over_it() {
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("c.sqlite");
    let pbf = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let import = |p: std::path::PathBuf| {
        let f = file.clone();
        async move {
            citymesh::commands::import::import(&[p], f.to_str().unwrap(), true)
                .await
                .unwrap()
        }
    };
    import(pbf.clone()).await;
    let inside = "/tiles/16/34297/22493.glb";
    // A tile far from Karlsruhe-Kirchfeld's data tiles.
    let elsewhere = "/tiles/16/34297/22430.glb";
    {
        let app = app_with(&dem_dir(), &file, &["--offline"]).await;
        assert_eq!(get(&app, inside).await.header("x-citymesh-cache"), "miss");
        assert_eq!(
            get(&app, elsewhere).await.header("x-citymesh-cache"),
            "miss"
        );
    }
    common::settle_writes().await;
    // The same data again changes nothing.
    let again = import(pbf).await;
    assert_eq!((again.changed_data_tiles, again.tiles_invalidated), (0, 0));
    // Other data over the same area (kirchfeld as Overpass JSON with one building less).
    let mut doc: Value =
        serde_json::from_slice(&osm_bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
    let elements = doc["elements"].as_array_mut().unwrap();
    let i = elements
        .iter()
        .position(|e| e["type"] == "way" && e["tags"].get("building").is_some())
        .unwrap();
    elements.remove(i);
    let changed = db.path().join("changed.json");
    std::fs::write(&changed, serde_json::to_vec(&doc).unwrap()).unwrap();
    let report = import(changed).await;
    assert!(report.changed_data_tiles >= 1);
    assert!(report.tiles_invalidated >= 1);
    let app = app_with(&dem_dir(), &file, &["--offline"]).await;
    assert_eq!(get(&app, inside).await.header("x-citymesh-cache"), "miss");
    assert_eq!(
        get(&app, elsewhere).await.header("x-citymesh-cache"),
        "sqlite"
    );
}

/// `scenes[0].extras` of a GLB.
fn scene_extras(gltf: &gltf::Gltf) -> Value {
    let raw = gltf.default_scene().unwrap().extras().clone().unwrap();
    serde_json::from_str(raw.get()).unwrap()
}

/// Ground vertices (lon, lat, height) of a GLB's `ground` primitive.
fn ground_vertices(glb: &[u8]) -> Vec<[f64; 3]> {
    let gltf = gltf::Gltf::from_slice(glb).unwrap();
    let extras = scene_extras(&gltf);
    let o = &extras["origin"];
    let frame = LocalFrame::new(
        o["lon"].as_f64().unwrap(),
        o["lat"].as_f64().unwrap(),
        o["height"].as_f64().unwrap(),
    );
    let blob = gltf.blob.as_deref().unwrap();
    let mut out = Vec::new();
    for mesh in gltf.meshes() {
        for prim in mesh.primitives() {
            if prim.material().name() != Some("ground") {
                continue;
            }
            for [x, y, z] in prim.reader(|_| Some(blob)).read_positions().unwrap() {
                let (lon, lat, h) =
                    frame.to_geographic([f64::from(x), -f64::from(z), f64::from(y)]);
                out.push([lon, lat, h]);
            }
        }
    }
    out
}

fn building_ids(glb: &[u8]) -> Vec<String> {
    let gltf = gltf::Gltf::from_slice(glb).unwrap();
    let extras = scene_extras(&gltf);
    extras["buildings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_owned())
        .collect()
}

#[tokio::test]
async fn import_then_offline_serves_every_building_once_with_seamless_ground() {
    let stub = Stub::new();
    let url = start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("c.sqlite");
    let pbf = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let report = citymesh::commands::import::import(&[pbf], file.to_str().unwrap(), true)
        .await
        .unwrap();
    assert_eq!(report.buildings, 2995 + 31);
    assert_eq!(report.skipped, 0);
    // Offline, though an upstream is named: it must never be called.
    let app = app_with(&dem_dir(), &file, &["--offline", "--overpass-url", &url]).await;

    // A 3 x 3 block of z16 tiles over the area.
    let (x0, y0) = (34295u32, 22490u32);
    let mut tiles = HashMap::new();
    for x in x0..x0 + 3 {
        for y in y0..y0 + 3 {
            let t = get(&app, &format!("/tiles/16/{x}/{y}.glb")).await;
            assert_eq!(t.status, StatusCode::OK);
            assert_eq!(t.header("x-citymesh-osm"), "stored");
            assert_valid_glb(&t.body);
            tiles.insert((x, y), t.body);
        }
    }
    assert_eq!(stub.count(), 0);

    // Each building once; exactly those of the clusters whose point is in the block, but for
    // outlines their parts cover.
    let mut seen = HashSet::new();
    for body in tiles.values() {
        for id in building_ids(body) {
            assert!(seen.insert(id.clone()), "{id} is in two tiles");
        }
    }
    let set = BuildingSet::new(
        read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    let in_block = |c: &citymesh_core::building::set::ClusterInfo| {
        let (lon, lat) = c.representative_point();
        let t = TileCoord::containing(16, lon, lat);
        (x0..x0 + 3).contains(&t.x) && (y0..y0 + 3).contains(&t.y)
    };
    let mut expected = HashSet::new();
    let mut outlines_with_parts = HashSet::new();
    for c in set.clusters().iter().filter(|c| in_block(c)) {
        let records = set.cluster_records(c);
        let has_parts = records.iter().any(|r| r.is_part);
        for r in records {
            expected.insert(r.id.to_string());
            if has_parts && !r.is_part {
                outlines_with_parts.insert(r.id.to_string());
            }
        }
    }
    assert!(seen.len() > 500, "{} buildings in the block", seen.len());
    assert!(seen.is_subset(&expected));
    for missing in expected.difference(&seen) {
        assert!(
            outlines_with_parts.contains(missing),
            "{missing} is in no tile"
        );
    }

    // Neighbours share their ground edge vertex for vertex.
    for x in x0..x0 + 2 {
        for y in y0..y0 + 3 {
            let edge = TileCoord { z: 16, x: x + 1, y }.bounds().min_lon();
            let on_edge = |body: &Vec<u8>| {
                let mut v: Vec<[i64; 3]> = ground_vertices(body)
                    .into_iter()
                    .filter(|p| (p[0] - edge).abs() < 1e-8)
                    .map(|p| [(p[1] * 1e8).round() as i64, (p[2] * 1e3).round() as i64, 0])
                    .collect();
                v.sort();
                v.dedup();
                v
            };
            let (a, b) = (on_edge(&tiles[&(x, y)]), on_edge(&tiles[&(x + 1, y)]));
            assert!(a.len() > 10, "{} vertices on the edge", a.len());
            assert_eq!(a, b, "the edge between {x},{y} and {},{y}", x + 1);
        }
    }
}

#[tokio::test]
async fn tiles_carry_etags_and_answer_304_with_cors() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let a = get(&app, "/tiles/16/34297/22492.glb").await;
    let etag = a.header("etag").to_owned();
    assert!(etag.starts_with('"') && etag.len() == 18, "{etag}");
    assert_eq!(a.header("cache-control"), "public, max-age=3600");
    let request = axum::http::Request::get("/tiles/16/34297/22492.glb")
        .header("if-none-match", &etag)
        .header("origin", "http://example.test")
        .body(axum::body::Body::empty())
        .unwrap();
    let r = tower::ServiceExt::oneshot(app.clone(), request)
        .await
        .unwrap();
    assert_eq!(r.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(r.headers()["etag"], etag.as_str());
    assert_eq!(r.headers()["access-control-allow-origin"], "*");
    // JSON is compressed when the client accepts gzip; GLB is not.
    for (uri, compressed) in [
        ("/openapi.json", true),
        ("/tiles/16/34297/22492.glb", false),
    ] {
        let request = axum::http::Request::get(uri)
            .header("accept-encoding", "gzip")
            .body(axum::body::Body::empty())
            .unwrap();
        let r = tower::ServiceExt::oneshot(app.clone(), request)
            .await
            .unwrap();
        assert_eq!(
            r.headers().get("content-encoding").is_some(),
            compressed,
            "{uri}"
        );
    }
}

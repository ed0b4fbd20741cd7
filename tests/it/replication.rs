//! Following a replication feed (issue 42) over imported Kirchfeld: a feed of `state.txt` and
//! `.osc.gz` files behind a small HTTP server on 127.0.0.1; each kind of edit shows in the
//! served tiles, exactly the generated tiles over the changed outlines are dropped, the rest
//! keep their ETags; a kill -9 while diffs are applied loses and repeats nothing; and every bad
//! feed is refused with the store as it was.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common::{self, app_with, data_dir, dem_dir, get};
use axum::extract::{Path as UrlPath, State};
use axum::http::StatusCode;
use citymesh::cache::TileStore;
use citymesh::commands::import::import_into;
use citymesh::db::{self, Database};
use citymesh::source::data_tiles::OsmTileStore;
use citymesh::source::data_tiles::replication::feed::{Feed, catch_up, sequence_path};
use citymesh_core::building::cluster::record_bounds;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, OsmBuildings, OsmId, read_buildings, unpack};
use clap::Parser as _;
use std::io::Write;
use std::path::{Path, PathBuf};

const MARGIN: f64 = 0.002;

async fn sqlite(path: &Path) -> Database {
    Database::Sqlite(db::open(path.to_str().unwrap()).await.unwrap())
}

/// A folder served over HTTP on 127.0.0.1; a file `NAME.status` beside `NAME` makes `NAME`
/// answer that status instead.
async fn serve_folder(dir: PathBuf) -> String {
    async fn file(
        State(dir): State<PathBuf>,
        UrlPath(path): UrlPath<String>,
    ) -> Result<Vec<u8>, StatusCode> {
        let p = dir.join(&path);
        if let Ok(s) = std::fs::read_to_string(format!("{}.status", p.display())) {
            return Err(StatusCode::from_u16(s.trim().parse().unwrap()).unwrap());
        }
        std::fs::read(p).map_err(|_| StatusCode::NOT_FOUND)
    }
    let app = axum::Router::new()
        .route("/{*path}", axum::routing::get(file))
        .with_state(dir);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    url
}

fn gz(text: &str) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(text.as_bytes()).unwrap();
    e.finish().unwrap()
}

fn state_txt(n: i64) -> String {
    format!(
        "#test feed\nsequenceNumber={n}\ntimestamp=2026-12-07T10\\:{:02}\\:00Z\n",
        n % 60
    )
}

/// Publishes sequence `n` with `body` (the inside of `<osmChange>`), and moves `state.txt` to it.
fn publish(feed: &Path, n: i64, body: &str) {
    publish_bytes(
        feed,
        n,
        &gz(&format!("<osmChange version=\"0.6\">{body}</osmChange>")),
    );
}

fn publish_bytes(feed: &Path, n: i64, osc_gz: &[u8]) {
    let path = feed.join(sequence_path(n));
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(format!("{}.osc.gz", path.display()), osc_gz).unwrap();
    std::fs::write(format!("{}.state.txt", path.display()), state_txt(n)).unwrap();
    std::fs::write(feed.join("state.txt"), state_txt(n)).unwrap();
}

fn kirchfeld() -> PathBuf {
    data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf")
}

fn way_xml(id: i64, nodes: &[i64], tags: &[(&str, &str)]) -> String {
    let nd: String = nodes.iter().map(|n| format!("<nd ref=\"{n}\"/>")).collect();
    let tg: String = tags
        .iter()
        .map(|(k, v)| format!("<tag k=\"{k}\" v=\"{v}\"/>"))
        .collect();
    format!("<way id=\"{id}\" version=\"9\">{nd}{tg}</way>")
}

fn closed_refs(r: &BuildingRecord) -> Vec<i64> {
    let ring = &r.outers[0].nodes;
    ring.iter()
        .chain(std::iter::once(&ring[0]))
        .map(|n| n.id.unwrap())
        .collect()
}

/// Every stored data tile's body.
async fn bodies(db: &Database) -> Vec<(TileCoord, Vec<u8>)> {
    let store = OsmTileStore::new(db.clone());
    let mut out = Vec::new();
    for t in store.stored_tiles().await.unwrap() {
        out.push((t, store.get(&t).await.unwrap().unwrap().body.to_vec()));
    }
    out
}

async fn stored_buildings(db: &Database) -> Vec<BuildingRecord> {
    let mut all: Vec<BuildingRecord> = Vec::new();
    for (_, b) in bodies(db).await {
        all.extend(unpack(&b).unwrap().buildings);
    }
    all.sort_by_key(|r| r.id);
    all.dedup_by_key(|r| r.id);
    all
}

/// The z16 tiles over Kirchfeld's buildings.
fn z16_tiles(osm: &OsmBuildings) -> Vec<TileCoord> {
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for r in &osm.buildings {
        let rb = record_bounds(r);
        b = [
            b[0].min(rb[0]),
            b[1].min(rb[1]),
            b[2].max(rb[2]),
            b[3].max(rb[3]),
        ];
    }
    TileCoord::covering(&GeoBbox::new(b[0], b[1], b[2], b[3]).unwrap(), 16)
        .tiles()
        .collect()
}

fn overlaps(t: &TileCoord, area: &[f64; 4]) -> bool {
    let b = t.bounds();
    b.min_lon() <= area[2]
        && b.max_lon() >= area[0]
        && b.min_lat() <= area[3]
        && b.max_lat() >= area[1]
}

fn grown(b: [f64; 4]) -> [f64; 4] {
    [b[0] - MARGIN, b[1] - MARGIN, b[2] + MARGIN, b[3] + MARGIN]
}

fn union(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

/// The feature row of a building in a served tile, if drawn there.
fn row(glb: &[u8], id: OsmId) -> Option<serde_json::Map<String, serde_json::Value>> {
    let (kind, n) = match id {
        OsmId::Way(n) => ("way", n),
        OsmId::Relation(n) => ("relation", n),
    };
    assert!(glb.starts_with(b"glTF"), "{}", String::from_utf8_lossy(glb));
    let n = n.to_string();
    common::decode::feature_rows(glb)
        .into_iter()
        .find(|r| r["osm_type"] == kind && r["osm_id"] == n.as_str())
}

/// The z16 tile that draws a building (its group's point is there): the one whose GLB has its row.
async fn tile_drawing(
    app: &axum::Router,
    id: OsmId,
    near: &BuildingRecord,
) -> (TileCoord, Vec<u8>) {
    let b = record_bounds(near);
    let around = GeoBbox::new(b[0], b[1], b[2], b[3]).unwrap();
    for t in TileCoord::covering(&around, 16).tiles() {
        let a = get(app, &format!("/tiles/16/{}/{}.glb", t.x, t.y)).await;
        if row(&a.body, id).is_some() {
            return (t, a.body);
        }
    }
    panic!("no z16 tile draws {id}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_kind_of_edit_shows_and_drops_exactly_the_tiles_over_it() {
    let dir = tempfile::tempdir().unwrap();
    let db_path = dir.path().join("c.sqlite");
    let db = sqlite(&db_path).await;
    import_into(&[kirchfeld()], &db, true).await.unwrap();
    let feed_dir = dir.path().join("feed");
    std::fs::create_dir_all(&feed_dir).unwrap();
    std::fs::write(feed_dir.join("state.txt"), state_txt(100)).unwrap();
    let url = serve_folder(feed_dir.clone()).await;
    let store = OsmTileStore::new(db.clone());
    let tiles = TileStore::open(&db, u64::MAX, "test").await.unwrap();
    let feed = Feed::new(&url).unwrap();

    let osm = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let ways: Vec<&BuildingRecord> = osm
        .buildings
        .iter()
        .filter(|r| matches!(r.id, OsmId::Way(_)) && !r.is_part && r.outers[0].nodes.len() >= 4)
        .collect();
    let relation = osm
        .buildings
        .iter()
        // One drawn whole: without parts (relation/1776559 is left empty by its parts and a
        // building drawn over the rest).
        .find(|r| {
            matches!(r.id, OsmId::Relation(_))
                && !r.is_part
                && !osm
                    .buildings
                    .iter()
                    .any(|p| p.is_part && citymesh_core::building::cluster::part_of(p, r))
        })
        .unwrap();
    let (raise, roof, moved, deleted) = (ways[10], ways[400], ways[800], ways[1200]);
    let grid = z16_tiles(&osm);

    // Sequence 100 is where the import stands: nothing to apply before 101.
    catch_up(&store, &tiles, &feed, Some(101), |_| {})
        .await
        .unwrap();
    assert_eq!(store.replication_state().await.unwrap(), None);

    // Each edit: (what it does, its body, the building it shows on, old and new outline).
    let new_id = OsmId::Way(990_000_000_001);
    let [w, s, _, _] = record_bounds(raise);
    let (lon, lat) = (w - 0.0006, s - 0.0004);
    let square = [(0.0, 0.0), (0.0001, 0.0), (0.0001, 0.00007), (0.0, 0.00007)];
    let new_nodes: String = square
        .iter()
        .enumerate()
        .map(|(i, (dx, dy))| {
            format!(
                "<node id=\"{}\" version=\"1\" lat=\"{:.7}\" lon=\"{:.7}\"/>",
                990_000_000_001 + i as i64,
                lat + dy,
                lon + dx
            )
        })
        .collect();
    let new_refs = [
        990_000_000_001,
        990_000_000_002,
        990_000_000_003,
        990_000_000_004,
        990_000_000_001,
    ];
    let moved_node = moved.outers[0].nodes[1];
    let seven = |v: f64| format!("{v:.7}").parse::<f64>().unwrap();
    let moved_to = (
        seven(moved_node.lon + 0.00003),
        seven(moved_node.lat + 0.00002),
    );
    let mut raise_tags = raise.tags.clone();
    raise_tags.insert("height".into(), "31.5".into());
    let mut roof_tags = roof.tags.clone();
    roof_tags.insert("roof:shape".into(), "gabled".into());
    let mut rel_tags = relation.tags.clone();
    rel_tags.insert("height".into(), "27".into());
    let rel_members = {
        let m = osm
            .member_ways
            .iter()
            .find(|m| OsmId::Relation(m.relation) == relation.id)
            .unwrap();
        m.ways
            .iter()
            .zip(&m.inner)
            .map(|(w, inner)| {
                format!(
                    "<member type=\"way\" ref=\"{w}\" role=\"{}\"/>",
                    if *inner { "inner" } else { "outer" }
                )
            })
            .collect::<String>()
    };
    let OsmId::Relation(rel_n) = relation.id else {
        unreachable!()
    };
    let tag_xml = |t: &std::collections::BTreeMap<String, String>| {
        t.iter()
            .map(|(k, v)| {
                format!(
                    "<tag k=\"{k}\" v=\"{}\"/>",
                    v.replace('"', "&quot;").replace('&', "&amp;")
                )
            })
            .collect::<String>()
    };
    let modify_way = |r: &BuildingRecord, tags: &std::collections::BTreeMap<String, String>| {
        let nd: String = closed_refs(r)
            .iter()
            .map(|n| format!("<nd ref=\"{n}\"/>"))
            .collect();
        let (OsmId::Way(id) | OsmId::Relation(id)) = r.id;
        format!(
            "<modify><way id=\"{id}\" version=\"9\">{nd}{}</way></modify>",
            tag_xml(tags)
        )
    };
    let id_of = |r: &BuildingRecord| match r.id {
        OsmId::Way(n) | OsmId::Relation(n) => n,
    };
    let new_outline = [lon, lat, lon + 0.0001, lat + 0.00007];
    let moved_after = {
        let mut m = moved.clone();
        m.outers[0].nodes[1].lon = moved_to.0;
        m.outers[0].nodes[1].lat = moved_to.1;
        record_bounds(&m)
    };
    let edits: Vec<(&str, String, OsmId, [f64; 4])> = vec![
        (
            "add a building",
            format!(
                "<create>{new_nodes}{}</create>",
                way_xml(
                    990_000_000_001,
                    &new_refs,
                    &[("building", "yes"), ("height", "7.5")]
                )
            ),
            new_id,
            new_outline,
        ),
        (
            "raise a height",
            modify_way(raise, &raise_tags),
            raise.id,
            record_bounds(raise),
        ),
        (
            "change a roof shape",
            modify_way(roof, &roof_tags),
            roof.id,
            record_bounds(roof),
        ),
        (
            "move a node",
            format!(
                "<modify><node id=\"{}\" version=\"5\" lat=\"{:.7}\" lon=\"{:.7}\"/></modify>",
                moved_node.id.unwrap(),
                moved_to.1,
                moved_to.0
            ),
            moved.id,
            union(record_bounds(moved), moved_after),
        ),
        (
            "delete a building",
            format!(
                "<delete><way id=\"{}\" version=\"9\"/></delete>",
                id_of(deleted)
            ),
            deleted.id,
            record_bounds(deleted),
        ),
        (
            "edit a multipolygon",
            format!(
                "<modify><relation id=\"{rel_n}\" version=\"9\">{rel_members}{}</relation></modify>",
                tag_xml(&rel_tags)
            ),
            relation.id,
            record_bounds(relation),
        ),
    ];

    for (i, (what, body, id, outline)) in edits.iter().enumerate() {
        let seq = 101 + i as i64;
        // Generate the grid's tiles (served from the store afterwards), note their ETags.
        let app = app_with(&dem_dir(), &db_path, &[]).await;
        let mut etags = Vec::new();
        for t in &grid {
            let a = get(&app, &format!("/tiles/16/{}/{}.glb", t.x, t.y)).await;
            assert_eq!(a.status, StatusCode::OK, "{what}");
            etags.push(a.header("etag").to_owned());
        }
        common::settle_writes().await;
        drop(app);
        let before = tiles.count().await.unwrap() as u64;

        publish(&feed_dir, seq, body);
        let reports = catch_up(&store, &tiles, &feed, Some(101), |_| {})
            .await
            .unwrap();
        assert_eq!(reports.len(), 1, "{what}");
        let r = &reports[0];
        assert_eq!(r.sequence, Some(seq));
        // Exactly the generated tiles over the old and new outline, grown by the margin.
        let area = grown(*outline);
        let expected = grid.iter().filter(|t| overlaps(t, &area)).count() as u64;
        assert!(expected > 0, "{what}");
        assert_eq!(r.tiles_dropped, expected, "{what}: {r:?}");
        assert_eq!(
            tiles.count().await.unwrap() as u64,
            before - expected,
            "{what}"
        );
        let state = store.replication_state().await.unwrap().unwrap();
        assert_eq!((state.sequence, state.url.as_str()), (seq, url.as_str()));

        // What a user sees now.
        let app = app_with(&dem_dir(), &db_path, &[]).await;
        for (t, etag) in grid.iter().zip(&etags) {
            if !overlaps(t, &area) {
                let a = get(&app, &format!("/tiles/16/{}/{}.glb", t.x, t.y)).await;
                assert_eq!(a.header("etag"), etag, "{what}: untouched {t:?}");
                assert_eq!(
                    a.header("x-citymesh-cache"),
                    "sqlite",
                    "{what}: {t:?} regenerated"
                );
            }
        }
        let stored = stored_buildings(&db).await;
        let now = stored.iter().find(|b| b.id == *id);
        match *what {
            "add a building" => {
                let b = now.expect("the new building is stored");
                let (_, glb) = tile_drawing(&app, *id, b).await;
                assert_eq!(row(&glb, *id).unwrap()["height"], "7.5");
            }
            "raise a height" => {
                let (_, glb) = tile_drawing(&app, *id, now.unwrap()).await;
                assert_eq!(row(&glb, *id).unwrap()["height"], "31.5");
            }
            "change a roof shape" => {
                let (_, glb) = tile_drawing(&app, *id, now.unwrap()).await;
                assert_eq!(row(&glb, *id).unwrap()["roof_shape"], "gabled");
            }
            "move a node" => {
                let n = now.unwrap().outers[0].nodes[1];
                assert_eq!((n.lon, n.lat), moved_to, "the node moved in the store");
                assert_eq!(record_bounds(now.unwrap()), moved_after);
            }
            "delete a building" => {
                assert!(now.is_none(), "deleted from every data tile");
                for t in grid.iter().filter(|t| overlaps(t, &area)) {
                    let a = get(&app, &format!("/tiles/16/{}/{}.glb", t.x, t.y)).await;
                    assert!(row(&a.body, *id).is_none(), "{id} still drawn in {t:?}");
                }
            }
            _ => {
                let (_, glb) = tile_drawing(&app, *id, now.unwrap()).await;
                assert_eq!(row(&glb, *id).unwrap()["height"], "27");
                // The 3D Tiles leaf over it shows it too.
                let c = now.unwrap().outers[0].nodes[0];
                let leaf = TileCoord::containing(15, c.lon, c.lat);
                let mut found = false;
                for x in leaf.x.saturating_sub(1)..=leaf.x + 1 {
                    for y in leaf.y.saturating_sub(1)..=leaf.y + 1 {
                        let a = get(&app, &format!("/3dtiles/world/15/{x}/{y}.glb")).await;
                        if a.status != StatusCode::OK {
                            continue;
                        }
                        if let Some(r) = row(&a.body, *id) {
                            assert_eq!(r["height"], "27");
                            found = true;
                        }
                    }
                }
                assert!(found, "no world leaf draws {id}");
            }
        }
        common::settle_writes().await;
    }
    // Nothing is applied twice: the feed has nothing new.
    let again = catch_up(&store, &tiles, &feed, Some(101), |_| {})
        .await
        .unwrap();
    assert!(again.is_empty());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_bad_feed_is_refused_with_the_store_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let db = sqlite(&dir.path().join("c.sqlite")).await;
    import_into(&[kirchfeld()], &db, true).await.unwrap();
    let feed_dir = dir.path().join("feed");
    std::fs::create_dir_all(&feed_dir).unwrap();
    let url = serve_folder(feed_dir.clone()).await;
    let store = OsmTileStore::new(db.clone());
    let tiles = TileStore::open(&db, u64::MAX, "test").await.unwrap();
    let feed = Feed::new(&url).unwrap();
    let osm = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let b = &osm.buildings[0];
    let good = format!(
        "<modify>{}</modify>",
        way_xml(
            match b.id {
                OsmId::Way(n) | OsmId::Relation(n) => n,
            },
            &closed_refs(b),
            &[("building", "yes"), ("height", "12.25")]
        )
    );
    // One good diff first: sequence 1.
    publish(&feed_dir, 1, &good);
    catch_up(&store, &tiles, &feed, Some(1), |_| {})
        .await
        .unwrap();
    let kept = bodies(&db).await;
    let refused = |e: String, want: &str| assert!(e.contains(want), "{want:?} not in: {e}");

    // The feed answers 500 for state.txt.
    std::fs::write(feed_dir.join("state.txt.status"), "500").unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "answered HTTP 500");
    std::fs::remove_file(feed_dir.join("state.txt.status")).unwrap();
    // A gap: state.txt names 3, sequence 2 is missing (404).
    publish(&feed_dir, 3, &good);
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "000/000/002.state.txt: answered HTTP 404");
    // Sequence 2 cut short (half its gzip).
    let full = gz(&format!("<osmChange version=\"0.6\">{good}</osmChange>"));
    publish_bytes(&feed_dir, 2, &full[..full.len() / 2]);
    std::fs::write(feed_dir.join("state.txt"), state_txt(3)).unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "000/000/002.osc.gz");
    // Malformed: not osmChange.
    publish_bytes(&feed_dir, 2, &gz("<osm><node id=\"1\"/></osm>"));
    std::fs::write(feed_dir.join("state.txt"), state_txt(3)).unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "not an <osmChange>");
    // Unknown nodes: a new building on nodes nobody has.
    publish(
        &feed_dir,
        2,
        &format!(
            "<create>{}</create>",
            way_xml(
                5,
                &[7_000_000_001, 7_000_000_002, 7_000_000_003, 7_000_000_001],
                &[("building", "yes")]
            )
        ),
    );
    std::fs::write(feed_dir.join("state.txt"), state_txt(3)).unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "way/5 refers to nodes");
    refused(e.to_string(), "7000000001, 7000000002, 7000000003");
    // A lying state: the file of sequence 2 says it is 9.
    publish(&feed_dir, 2, &good);
    let p = feed_dir.join(format!("{}.state.txt", sequence_path(2)));
    std::fs::write(&p, state_txt(9)).unwrap();
    std::fs::write(feed_dir.join("state.txt"), state_txt(3)).unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "names sequence 9, not 2");
    // A state.txt behind the store.
    std::fs::write(feed_dir.join("state.txt"), state_txt(0)).unwrap();
    let e = catch_up(&store, &tiles, &feed, None, |_| {})
        .await
        .unwrap_err();
    refused(e.to_string(), "behind the 1 this store applied");
    // After every refusal: the store as after sequence 1.
    assert_eq!(bodies(&db).await, kept);
    assert_eq!(
        store.replication_state().await.unwrap().unwrap().sequence,
        1
    );
    // Fixed, the feed goes on from 2.
    std::fs::write(&p, state_txt(2)).unwrap();
    std::fs::write(feed_dir.join("state.txt"), state_txt(3)).unwrap();
    let r = catch_up(&store, &tiles, &feed, None, |_| {}).await.unwrap();
    assert_eq!(
        r.iter().map(|r| r.sequence).collect::<Vec<_>>(),
        vec![Some(2), Some(3)]
    );
}

/// Diffs that each raise the height of 150 buildings (a different 150 each time).
fn height_diffs(osm: &OsmBuildings, n: usize) -> Vec<String> {
    let ways: Vec<&BuildingRecord> = osm
        .buildings
        .iter()
        .filter(|r| matches!(r.id, OsmId::Way(_)))
        .collect();
    (0..n)
        .map(|k| {
            let edits: String = ways
                .iter()
                .skip(k * 150)
                .take(150)
                .map(|r| {
                    let OsmId::Way(id) = r.id else { unreachable!() };
                    let h = format!("{}.5", 10 + k);
                    way_xml(id, &closed_refs(r), &[("building", "yes"), ("height", &h)])
                })
                .collect();
            format!("<modify>{edits}</modify>")
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_kill_during_the_diffs_loses_and_repeats_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (killed_path, straight_path) = (dir.path().join("k.sqlite"), dir.path().join("s.sqlite"));
    let killed = sqlite(&killed_path).await;
    let straight = sqlite(&straight_path).await;
    import_into(&[kirchfeld()], &killed, true).await.unwrap();
    import_into(&[kirchfeld()], &straight, true).await.unwrap();
    let feed_dir = dir.path().join("feed");
    std::fs::create_dir_all(&feed_dir).unwrap();
    let osm = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    const DIFFS: usize = 12;
    for (k, body) in height_diffs(&osm, DIFFS).iter().enumerate() {
        publish(&feed_dir, 1 + k as i64, body);
    }
    let url = serve_folder(feed_dir.clone()).await;

    // Uninterrupted, in this process.
    let feed = Feed::new(&url).unwrap();
    let store = OsmTileStore::new(straight.clone());
    let tiles = TileStore::open(&straight, u64::MAX, "test").await.unwrap();
    let all = catch_up(&store, &tiles, &feed, Some(1), |_| {})
        .await
        .unwrap();
    assert_eq!(all.len(), DIFFS);
    let want = bodies(&straight).await;

    // The binary, killed once it reported its first diff (it is fetching or applying the next).
    let run = |path: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
            .args(["replicate", "--once", "--from-sequence", "1", "--url", &url])
            .args(["--cache-db", path.to_str().unwrap()])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap()
    };
    let sequences_in = |text: &str| -> Vec<i64> {
        text.lines()
            .filter_map(|l| l.strip_prefix("sequence ")?.split(':').next()?.parse().ok())
            .collect()
    };
    let mut child = run(&killed_path);
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    std::io::BufRead::read_line(&mut out, &mut first).unwrap();
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let mut seen = sequences_in(&first);
    assert_eq!(seen, vec![1], "{first}");
    let stopped_at = OsmTileStore::new(killed.clone())
        .replication_state()
        .await
        .unwrap()
        .unwrap()
        .sequence;
    assert!(
        stopped_at < DIFFS as i64,
        "the kill came too late to test anything"
    );

    // Run again: it goes on after the last diff committed, each diff once.
    let again = run(&killed_path).wait_with_output().unwrap();
    assert!(again.status.success());
    let rest = sequences_in(&String::from_utf8_lossy(&again.stdout));
    assert_eq!(rest.first(), Some(&(stopped_at + 1)));
    seen.extend(&rest);
    let mut distinct = seen.clone();
    distinct.dedup();
    assert_eq!(seen, distinct, "a diff was applied twice");
    assert_eq!(*seen.last().unwrap(), DIFFS as i64);
    // The same store as without the kill.
    assert_eq!(bodies(&killed).await, want);
    let s = OsmTileStore::new(killed.clone())
        .replication_state()
        .await
        .unwrap()
        .unwrap();
    assert_eq!(s.sequence, DIFFS as i64);
}

/// The version the world tileset names for leaf `t` (`?v=`), from the zoom-12 file holding it.
async fn leaf_version(app: &axum::Router, t: &TileCoord) -> String {
    let file = format!("/3dtiles/world/12/{}/{}.json", t.x >> 3, t.y >> 3);
    let text = get(app, &file).await.text();
    let at = format!("15/{}/{}.glb?v=", t.x, t.y);
    let i = text
        .find(&at)
        .unwrap_or_else(|| panic!("{file} lists no {at}"))
        + at.len();
    text[i..i + 16].to_owned()
}

/// The world leaf drawing a building.
async fn leaf_drawing(app: &axum::Router, id: OsmId, near: &BuildingRecord) -> TileCoord {
    let b = record_bounds(near);
    let around = GeoBbox::new(b[0], b[1], b[2], b[3]).unwrap();
    for t in TileCoord::covering(&around, 15).tiles() {
        let a = get(app, &format!("/3dtiles/world/15/{}/{}.glb", t.x, t.y)).await;
        if a.status == StatusCode::OK && row(&a.body, id).is_some() {
            return t;
        }
    }
    panic!("no world leaf draws {id}");
}

/// Polls `/health` until the data is at `sequence` (a minute at most).
async fn until_sequence(app: &axum::Router, sequence: i64) -> serde_json::Value {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let h = get(app, "/health").await.json();
        if h["replication"]["sequence"] == sequence {
            return h;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the server never applied sequence {sequence}: {h}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_following_a_feed_serves_each_change_and_says_how_fresh_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let db_path = dir.path().join("c.sqlite");
    let db = sqlite(&db_path).await;
    import_into(&[kirchfeld()], &db, true).await.unwrap();
    let feed_dir = dir.path().join("feed");
    std::fs::create_dir_all(&feed_dir).unwrap();
    std::fs::write(feed_dir.join("state.txt"), state_txt(40)).unwrap();
    let url = serve_folder(feed_dir.clone()).await;
    let args = citymesh::cli::ServeArgs::parse_from([
        "serve",
        "--offline",
        "--dem-dir",
        dem_dir().to_str().unwrap(),
        "--cache-db",
        db_path.to_str().unwrap(),
        "--replicate-url",
        &url,
        "--replicate-from-sequence",
        "41",
        "--replicate-interval-s",
        "1",
    ]);
    let state = citymesh::server::build_state(&args).await.unwrap();
    common::world_ready(&state).await;
    let app = common::app_of(state);
    let h = get(&app, "/health").await.json();
    assert!(h["replication"].is_null(), "{h}");

    // The tile drawing a building, held in memory by this server.
    let osm = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let b = osm
        .buildings
        .iter()
        .filter(|r| matches!(r.id, OsmId::Way(_)) && !r.is_part)
        .nth(77)
        .unwrap();
    let (t, glb) = tile_drawing(&app, b.id, b).await;
    assert_ne!(row(&glb, b.id).unwrap()["height"], "44.25");
    // What a client (or a CDN) holds before the diff: the tileset, with its ETag, and the
    // versioned URLs of the changed building's leaf and of a leaf far from it.
    let tileset = get(&app, "/3dtiles/tileset.json").await;
    assert_eq!(tileset.header("cache-control"), "public, max-age=60");
    let tileset_etag = tileset.header("etag").to_owned();
    let revalidated = common::send(
        &app,
        axum::http::Request::get("/3dtiles/tileset.json")
            .header("if-none-match", &tileset_etag)
            .body(axum::body::Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(revalidated.status, StatusCode::NOT_MODIFIED);
    let leaf = leaf_drawing(&app, b.id, b).await;
    let far = osm
        .buildings
        .iter()
        .find(|r| {
            let rb = record_bounds(r);
            let bb = record_bounds(b);
            !r.is_part && ((rb[0] - bb[0]).abs() > 0.01 || (rb[1] - bb[1]).abs() > 0.01)
        })
        .unwrap();
    let far_leaf = leaf_drawing(&app, far.id, far).await;
    let (old_v, far_v) = (
        leaf_version(&app, &leaf).await,
        leaf_version(&app, &far_leaf).await,
    );
    let old_url = format!("/3dtiles/world/15/{}/{}.glb?v={old_v}", leaf.x, leaf.y);
    let far_url = format!(
        "/3dtiles/world/15/{}/{}.glb?v={far_v}",
        far_leaf.x, far_leaf.y
    );
    let before = get(&app, &old_url).await;
    assert_eq!(
        before.header("cache-control"),
        "public, max-age=31536000, immutable"
    );
    let far_before = get(&app, &far_url).await;
    let OsmId::Way(id) = b.id else { unreachable!() };
    publish(
        &feed_dir,
        41,
        &format!(
            "<modify>{}</modify>",
            way_xml(
                id,
                &closed_refs(b),
                &[("building", "yes"), ("height", "44.25")]
            )
        ),
    );
    let h = until_sequence(&app, 41).await;
    assert_eq!(h["replication"]["timestamp"], "2026-12-07T10:41:00Z");
    assert_eq!(h["replication"]["url"], url.as_str());
    assert!(h["replication"]["age_s"].as_i64().unwrap() >= 0);
    // The same server, no restart: the tile shows the new height. /health shows the sequence
    // once its transaction commits; the tiles over the change are dropped just after, so the
    // tile is asked again until it shows it (a tile left stale would fail at the deadline).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let tile = format!("/tiles/16/{}/{}.glb", t.x, t.y);
    let mut height = row(&get(&app, &tile).await.body, b.id).unwrap()["height"].clone();
    while height != "44.25" && std::time::Instant::now() < deadline {
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        height = row(&get(&app, &tile).await.body, b.id).unwrap()["height"].clone();
    }
    assert_eq!(height, "44.25");
    // The CDN check. The tree is made again over the change (in the background): wait for the
    // leaf's new version.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let new_v = loop {
        let v = leaf_version(&app, &leaf).await;
        if v != old_v {
            break v;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the leaf's version never changed"
        );
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    };
    // The old URL of the changed leaf is gone, clearly; the new one has the change, for good.
    let stale = get(&app, &old_url).await;
    assert_eq!(stale.status, StatusCode::NOT_FOUND);
    assert_eq!(stale.json()["error"], "stale_version", "{}", stale.text());
    let new_url = format!("/3dtiles/world/15/{}/{}.glb?v={new_v}", leaf.x, leaf.y);
    let fresh = get(&app, &new_url).await;
    assert_eq!(
        fresh.header("cache-control"),
        "public, max-age=31536000, immutable"
    );
    assert_eq!(row(&fresh.body, b.id).unwrap()["height"], "44.25");
    assert_ne!(fresh.header("etag"), before.header("etag"));
    // A leaf far from the change keeps its URL and its bytes.
    assert_eq!(leaf_version(&app, &far_leaf).await, far_v);
    let far_after = get(&app, &far_url).await;
    assert_eq!(far_after.status, StatusCode::OK);
    assert_eq!(far_after.header("etag"), far_before.header("etag"));
    // The tileset revalidates to a new ETag.
    let ts = get(&app, "/3dtiles/tileset.json").await;
    assert_ne!(ts.header("etag"), tileset_etag);
    // The tileset and the metrics say how fresh it is.
    let ts = ts.json();
    assert_eq!(
        ts["asset"]["extras"]["citymesh"]["replication"],
        serde_json::json!({"sequence": 41, "timestamp": "2026-12-07T10:41:00Z"})
    );
    let m = get(&app, "/metrics").await.text();
    assert!(
        m.contains("citymesh_replication_diffs_applied_total 1\n"),
        "{m}"
    );
    assert!(m.contains("citymesh_replication_sequence 41\n"), "{m}");
    assert!(m.contains("citymesh_replication_lag_seconds "), "{m}");
    // A broken diff: the server keeps serving the last good data and counts the error.
    publish_bytes(&feed_dir, 42, b"not gzip, not xml");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let m = get(&app, "/metrics").await.text();
        if !m.contains("citymesh_replication_errors_total 0\n") {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "the error was never counted"
        );
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
    }
    let a = get(&app, &format!("/tiles/16/{}/{}.glb", t.x, t.y)).await;
    assert_eq!(a.status, StatusCode::OK);
    assert_eq!(row(&a.body, b.id).unwrap()["height"], "44.25");
    assert_eq!(
        get(&app, "/health").await.json()["replication"]["sequence"],
        41
    );
}

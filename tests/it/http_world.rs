//! The world tileset over HTTP on the real Karlsruhe-Kirchfeld data: one tree over everything
//! the server holds, in nested tileset files of bounded size, whose every content tile is valid
//! glTF inside its tile's bounding region, with every building drawn once at every level that
//! draws buildings, and blocks above them.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use clap::Parser;
use common::{assert_valid_glb, get};
use serde_json::Value;
use std::collections::BTreeMap;

/// A tile listed in a tileset file: its content URI (resolved), region and error, and its
/// parent's region and error.
struct Listed {
    uri: String,
    region: Vec<f64>,
    error: f64,
}

/// A parent's region and geometric error.
type Bound = (Vec<f64>, f64);

fn region_of(tile: &Value) -> Vec<f64> {
    tile["boundingVolume"]["region"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// `base` (a tileset file's path) joined with a relative URI.
fn resolve(base: &str, uri: &str) -> String {
    let mut parts: Vec<&str> = base.split('/').collect();
    parts.pop();
    for p in uri.split('/') {
        match p {
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

/// Walks a tileset file's tiles: checks that each parent's region holds its children's and that
/// errors do not grow downwards, follows external tilesets, and collects the content.
async fn walk(app: &axum::Router, path: &str, files: &mut usize, out: &mut Vec<Listed>) {
    let answer = get(app, path).await;
    assert_eq!(answer.status, StatusCode::OK, "{path}: {}", answer.text());
    *files += 1;
    let file = answer.json();
    assert_eq!(file["asset"]["version"], "1.1");
    let mut count = 0;
    let mut stack: Vec<(&Value, Option<Bound>)> = vec![(&file["root"], None)];
    let mut external = Vec::new();
    while let Some((tile, parent)) = stack.pop() {
        count += 1;
        let region = region_of(tile);
        let error = tile["geometricError"].as_f64().unwrap();
        if let Some((p, pe)) = &parent {
            assert!(
                p[0] <= region[0]
                    && p[1] <= region[1]
                    && p[2] >= region[2]
                    && p[3] >= region[3]
                    && p[4] <= region[4]
                    && p[5] >= region[5],
                "{path}: {region:?} outside its parent {p:?}"
            );
            assert!(
                error <= *pe,
                "{path}: error {error} above its parent's {pe}"
            );
        }
        if let Some(uri) = tile["content"]["uri"].as_str() {
            let resolved = resolve(path, uri);
            if uri.ends_with(".json") {
                assert!(tile["children"].is_null());
                external.push(resolved);
            } else {
                out.push(Listed {
                    uri: resolved,
                    region: region.clone(),
                    error,
                });
            }
        }
        for c in tile["children"].as_array().map_or(&[][..], |c| &c[..]) {
            stack.push((c, Some((region.clone(), error))));
        }
    }
    // 1 + 4 + 16 tiles with content and 64 references at most: bounded whatever the area.
    assert!(count <= 85, "{path} lists {count} tiles");
    for e in external {
        Box::pin(walk(app, &e, files, out)).await;
    }
}

/// Every vertex of the content `glb` lies inside its tile's region.
fn assert_inside(glb: &[u8], l: &Listed) {
    assert_valid_glb(&common::decode::decode_meshopt(glb));
    common::decode::assert_inside_region(glb, &l.region, &l.uri);
}

/// The zoom of a content path `/3dtiles/world/{z}/{x}/{y}.glb`.
fn zoom_of(uri: &str) -> u8 {
    uri.split('/').rev().nth(2).unwrap().parse().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_world_tileset_holds_every_building_once_per_level_inside_its_regions() {
    let db = tempfile::tempdir().unwrap();
    let state = common::kirchfeld_state(&db).await;
    let app = common::app_of(state.clone());
    let progress = common::world_ready(&state).await;
    // Kirchfeld's groups lie in 4 data tiles (zoom 14).
    assert_eq!(progress.data_tiles, 4, "{progress:?}");

    let mut files = 0;
    let mut listed = Vec::new();
    walk(&app, "/3dtiles/tileset.json", &mut files, &mut listed).await;
    // The root file (zooms 0-2), then one file each at zooms 3, 6 and 9 on the way down, then
    // the zoom-12 file that lists everything down to the leaves (zoom 15) itself.
    let mut at: BTreeMap<u8, usize> = BTreeMap::new();
    for l in &listed {
        *at.entry(zoom_of(&l.uri)).or_default() += 1;
    }
    println!("{files} tileset files; content tiles by zoom: {at:?}");
    assert_eq!(at.keys().copied().min(), Some(9), "no content above zoom 9");
    assert_eq!(at.get(&14), Some(&4));
    assert_eq!(at.get(&15), Some(&16));
    assert_eq!(
        at.keys().copied().max(),
        Some(15),
        "the leaves are at zoom 15"
    );
    assert_eq!(files, 5, "tileset files at zooms 0, 3, 6, 9 and 12");

    let mut rows_at: BTreeMap<u8, usize> = BTreeMap::new();
    let mut ids_at: BTreeMap<u8, std::collections::BTreeSet<String>> = BTreeMap::new();
    for l in &listed {
        let c = get(&app, &l.uri).await;
        assert_eq!(c.status, StatusCode::OK, "{}", l.uri);
        assert_valid_glb(&c.body);
        assert_inside(&c.body, l);
        let z = zoom_of(&l.uri);
        let rows = common::decode::feature_rows(&c.body);
        *rows_at.entry(z).or_default() += rows.len();
        for row in rows {
            let id = format!("{}/{}", row["elementType"], row["elementId"]);
            assert!(
                ids_at.entry(z).or_default().insert(id.clone()),
                "{id} twice at {z}"
            );
        }
        if z == 15 {
            assert_eq!(l.error, 0.0);
        } else {
            // A block's error is at least its cell's diagonal: 16 x 16 cells over the tile.
            let cell_m = 40_075_016.7 * 49.44_f64.to_radians().cos() / f64::from(1u32 << (z + 4));
            assert!(
                l.error >= cell_m * 2f64.sqrt() * 0.99,
                "{}: {}",
                l.uri,
                l.error
            );
        }
    }
    println!("features by zoom: {rows_at:?}");
    // At the leaves, every building and part once (3,026 records, 7 outlines wholly covered by
    // their parts); above, blocks, each a cell's buildings merged.
    assert_eq!(rows_at[&15], 3018, "zoom 15");
    // A block is a cell of a 16 x 16 grid (the tiles four zooms down) holding groups'
    // representative points: as many blocks as such cells (groups that cannot be built aside).
    let set = citymesh_core::building::set::BuildingSet::new(
        citymesh_core::osm::read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    for z in 9..=14u8 {
        let cells: std::collections::BTreeSet<_> =
            set.clusters().iter().map(|c| c.xyz_tile(z + 4)).collect();
        assert_eq!(rows_at[&z], cells.len(), "zoom {z}");
    }
}

#[tokio::test]
async fn world_files_refuse_what_is_not_in_the_tree() {
    let db = tempfile::tempdir().unwrap();
    let state = common::kirchfeld_state(&db).await;
    let app = common::app_of(state.clone());
    common::world_ready(&state).await;
    for (path, status, code) in [
        // Far from Karlsruhe: no data there.
        (
            "/3dtiles/world/14/0/0.glb",
            StatusCode::NOT_FOUND,
            "no_such_tile",
        ),
        (
            "/3dtiles/world/3/0/0.json",
            StatusCode::NOT_FOUND,
            "no_such_tile",
        ),
        // Above zoom 9 tiles only lead the way down.
        (
            "/3dtiles/world/3/4/2.glb",
            StatusCode::NOT_FOUND,
            "no_content",
        ),
        // The leaves are at zoom 15.
        (
            "/3dtiles/world/16/34298/22495.glb",
            StatusCode::NOT_FOUND,
            "no_such_tile",
        ),
        (
            "/3dtiles/world/17/1/1.glb",
            StatusCode::NOT_FOUND,
            "no_such_tile",
        ),
        (
            "/3dtiles/world/2/4/0.glb",
            StatusCode::NOT_FOUND,
            "no_such_tile",
        ),
        (
            "/3dtiles/world/14/8574/5623.png",
            StatusCode::NOT_FOUND,
            "unknown_format",
        ),
        (
            "/3dtiles/world/x/1/1.glb",
            StatusCode::BAD_REQUEST,
            "invalid_tile",
        ),
    ] {
        let a = get(&app, path).await;
        assert_eq!(a.status, status, "{path}: {}", a.text());
        assert_eq!(a.json()["error"], code, "{path}");
    }
    // A data tile's file and content exist.
    assert_eq!(
        get(&app, "/3dtiles/world/14/8574/5623.glb").await.status,
        StatusCode::OK
    );
    assert_eq!(
        get(&app, "/3dtiles/world/12/2143/1405.json").await.status,
        StatusCode::OK
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_reads_the_kept_summaries_and_serves_the_same_tree() {
    let db = tempfile::tempdir().unwrap();
    let first = common::kirchfeld_state(&db).await;
    let made = common::world_ready(&first).await;
    // Made from the buildings the first time, and kept.
    assert_eq!(
        (made.data_tiles, made.done, made.kept),
        (4, 4, 0),
        "{made:?}"
    );
    let app = common::app_of(first.clone());
    let tree = get(&app, "/3dtiles/world/12/2143/1405.json").await;
    assert_eq!(tree.status, StatusCode::OK);
    let block = get(&app, "/3dtiles/world/14/8574/5623.glb").await;
    assert_eq!(block.status, StatusCode::OK);
    common::settle_writes().await;

    // The next start reads all four instead of the data tiles' buildings.
    let again = common::kirchfeld_state(&db).await;
    let read = common::world_ready(&again).await;
    assert_eq!(
        (read.data_tiles, read.done, read.kept),
        (4, 4, 4),
        "{read:?}"
    );
    assert_eq!(read.held, made.held);
    let app = common::app_of(again);
    let tree_again = get(&app, "/3dtiles/world/12/2143/1405.json").await;
    assert_eq!(tree_again.json(), tree.json());
    let block_again = get(&app, "/3dtiles/world/14/8574/5623.glb").await;
    assert_eq!(block_again.body, block.body);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn world_content_goes_gzipped_to_who_accepts_it_and_inflated_to_the_rest() {
    let db = tempfile::tempdir().unwrap();
    let state = common::kirchfeld_state(&db).await;
    common::world_ready(&state).await;
    let app = common::app_of(state);
    let ask = |path: &'static str, encoding: Option<&'static str>| {
        let mut r = axum::http::Request::get(path);
        if let Some(e) = encoding {
            r = r.header("accept-encoding", e);
        }
        common::send(&app, r.body(axum::body::Body::empty()).unwrap())
    };
    for path in [
        "/3dtiles/world/14/8574/5623.glb",
        "/3dtiles/world/15/17149/11247.glb",
    ] {
        let plain = ask(path, None).await;
        let gzipped = ask(path, Some("br;q=1.0, gzip;q=0.8")).await;
        let refused = ask(path, Some("gzip;q=0")).await;
        assert_eq!(plain.status, StatusCode::OK, "{path}: {}", plain.text());
        assert_eq!(gzipped.status, StatusCode::OK, "{path}");
        assert!(plain.headers.get("content-encoding").is_none(), "{path}");
        assert!(refused.headers.get("content-encoding").is_none(), "{path}");
        assert_eq!(gzipped.header("content-encoding"), "gzip", "{path}");
        assert!(gzipped.header("vary").contains("accept-encoding"), "{path}");
        // The same content either way, under two validators.
        let inflated = citymesh::cache::content_coding::gunzip(&gzipped.body).unwrap();
        assert_eq!(&inflated[..], &plain.body[..], "{path}");
        assert_eq!(refused.body, plain.body, "{path}");
        assert_valid_glb(&plain.body);
        assert_ne!(plain.header("etag"), gzipped.header("etag"), "{path}");
        assert!(gzipped.body.len() < plain.body.len(), "{path}");
        println!(
            "{path}: {} bytes, {} gzipped",
            plain.body.len(),
            gzipped.body.len()
        );
    }
}

/// A server over imported data that also fetches from an upstream: the world tileset covers
/// what is stored, so its tiles at the edge of the import are made from the stored data tiles
/// alone and never wait on (or fail with) the upstream for the data tiles beside them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn world_tiles_at_the_edge_of_an_import_never_ask_upstream() {
    let db = tempfile::tempdir().unwrap();
    let store = db.path().join("c.sqlite");
    let pbf = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    citymesh::commands::import::import(&[pbf], store.to_str().unwrap(), true)
        .await
        .unwrap();
    // An upstream nobody answers at: asking it fails the request at once.
    let dem = common::dem_dir();
    let args = citymesh::cli::ServeArgs::parse_from([
        "serve",
        "--dem-dir",
        dem.to_str().unwrap(),
        "--cache-db",
        store.to_str().unwrap(),
        "--overpass-url",
        "http://127.0.0.1:9/api/interpreter",
        "--overpass-retries",
        "0",
    ]);
    let state = citymesh::server::build_state(&args).await.unwrap();
    let app = common::app_of(state.clone());
    assert_eq!(common::world_ready(&state).await.data_tiles, 4);

    let mut files = 0;
    let mut listed = Vec::new();
    walk(&app, "/3dtiles/tileset.json", &mut files, &mut listed).await;
    let mut rows = 0;
    for l in listed.iter().filter(|l| zoom_of(&l.uri) == 15) {
        let c = get(&app, &l.uri).await;
        assert_eq!(c.status, StatusCode::OK, "{}: {}", l.uri, c.text());
        rows += common::decode::feature_rows(&c.body).len();
    }
    // Every building of the import, as from its PBF file.
    assert_eq!(rows, 3018);
    // The upstream is live for what is not stored: a tile beside the import asks it and fails.
    let beside = get(&app, "/tiles/16/34290/22490.glb").await;
    assert_eq!(beside.status, StatusCode::BAD_GATEWAY, "{}", beside.text());
}

/// A server that fetches from Overpass, told to cover an area it holds nothing of yet
/// (`--world-area`): the tree covers the area at once, its leaves fetch their data tiles when a
/// client asks for them (the tileset files never do), and once fetched the area draws blocks
/// above the leaves like imported data.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_world_area_is_covered_before_its_data_is_fetched_and_its_leaves_fetch_it() {
    let stub = crate::http_serving::Stub::new();
    let url = crate::http_serving::start_stub(stub.clone()).await;
    let db = tempfile::tempdir().unwrap();
    let store = db.path().join("c.sqlite");
    let dem = common::dem_dir();
    // Inside data tile 14/8574/5623 (Kirchfeld's north-west quarter), away from its borders.
    let area = "8.3950,49.0390,8.4140,49.0510";
    let serve = |extra: &[&str]| {
        let mut args = vec![
            "serve",
            "--dem-dir",
            dem.to_str().unwrap(),
            "--cache-db",
            store.to_str().unwrap(),
            "--world-area",
            area,
        ];
        args.extend_from_slice(extra);
        citymesh::cli::ServeArgs::parse_from(args)
    };
    // Nothing to fetch from: refused with a reason.
    let refused = citymesh::server::build_state(&serve(&["--offline"])).await;
    let message = refused
        .err()
        .expect("--world-area with --offline")
        .to_string();
    assert!(message.contains("--world-area"), "{message}");

    let state =
        citymesh::server::build_state(&serve(&["--overpass-url", &url, "--overpass-retries", "0"]))
            .await
            .unwrap();
    let app = common::app_of(state.clone());
    assert_eq!(common::world_ready(&state).await.data_tiles, 0);

    let mut files = 0;
    let mut listed = Vec::new();
    walk(&app, "/3dtiles/tileset.json", &mut files, &mut listed).await;
    assert_eq!(files, 5, "tileset files at zooms 0, 3, 6, 9 and 12");
    // The root is the area grown by the largest building's extent (2 km), not the Earth.
    let root = region_of(&get(&app, "/3dtiles/tileset.json").await.json()["root"]);
    let grown_deg = |metres: f64, cos: f64| (metres / 110_500.0 / cos).to_radians();
    let (lat_m, lon_m) = (
        grown_deg(2_000.0, 1.0),
        grown_deg(2_000.0, 49.051_f64.to_radians().cos()),
    );
    let want = [
        8.3950_f64.to_radians() - lon_m,
        49.0390_f64.to_radians() - lat_m,
        8.4140_f64.to_radians() + lon_m,
        49.0510_f64.to_radians() + lat_m,
    ];
    for (got, want) in root.iter().zip(want) {
        assert!((got - want).abs() < 1e-7, "root {root:?}, want {want:?}");
    }
    assert_eq!((root[4], root[5]), (-500.0, 9_700.0));
    // Nothing held: content only at the leaves, the four of the one data tile the area lies in.
    let mut uris: Vec<String> = listed.iter().map(|l| l.uri.clone()).collect();
    uris.sort_unstable();
    assert_eq!(
        uris,
        [
            "/3dtiles/world/15/17148/11246.glb",
            "/3dtiles/world/15/17148/11247.glb",
            "/3dtiles/world/15/17149/11246.glb",
            "/3dtiles/world/15/17149/11247.glb",
        ]
    );
    assert_eq!(stub.count(), 0, "a tileset file never fetches");
    // Outside the area there is no tree.
    let outside = get(&app, "/3dtiles/world/15/17150/11247.glb").await;
    assert_eq!(outside.status, StatusCode::NOT_FOUND, "{}", outside.text());

    // A leaf fetches its data tile, and its buildings lie inside the region listed before.
    let mut rows = 0;
    for l in &listed {
        let c = get(&app, &l.uri).await;
        assert_eq!(c.status, StatusCode::OK, "{}: {}", l.uri, c.text());
        assert_inside(&c.body, l);
        rows += common::decode::feature_rows(&c.body).len();
    }
    let fetched = stub.count();
    println!("{rows} buildings in the 4 leaves; {fetched} data tiles fetched");
    // Each leaf reads the data tiles within its margin: its own and the three beside its
    // corner, so the four corners of one data tile read the 3 x 3 around it.
    assert_eq!(fetched, 9);
    // The same buildings as a server over the Kirchfeld file draws in the same leaves.
    let files_db = tempfile::tempdir().unwrap();
    let file_state = common::kirchfeld_state(&files_db).await;
    common::world_ready(&file_state).await;
    let from_file = common::app_of(file_state);
    let mut rows_from_file = 0;
    for l in &listed {
        let c = get(&from_file, &l.uri).await;
        assert_eq!(c.status, StatusCode::OK, "{}", l.uri);
        rows_from_file += common::decode::feature_rows(&c.body).len();
    }
    assert_eq!(rows, rows_from_file);

    // The data tile fetched is summarised: the tree draws blocks above its leaves, whose
    // buildings are the same, now read from the store.
    let data_tile = citymesh_core::geo::TileCoord {
        z: 14,
        x: 8574,
        y: 5623,
    };
    tokio::time::timeout(
        std::time::Duration::from_secs(60),
        state.summaries.summarised(&data_tile),
    )
    .await
    .expect("the fetched data tile was never summarised");
    let mut again = Vec::new();
    files = 0;
    walk(&app, "/3dtiles/tileset.json", &mut files, &mut again).await;
    let mut at: BTreeMap<u8, usize> = BTreeMap::new();
    for l in &again {
        *at.entry(zoom_of(&l.uri)).or_default() += 1;
    }
    assert_eq!(
        at.keys().copied().min(),
        Some(9),
        "blocks from zoom 9: {at:?}"
    );
    let mut rows_again = 0;
    // Now held, the leaves name the version of their data (`?v=`); the same files.
    let path = |uri: &str| uri.split('?').next().unwrap_or(uri).to_owned();
    for l in again.iter().filter(|l| uris.contains(&path(&l.uri))) {
        let c = get(&app, &l.uri).await;
        assert_eq!(c.status, StatusCode::OK, "{}", l.uri);
        assert_inside(&c.body, l);
        rows_again += common::decode::feature_rows(&c.body).len();
    }
    assert_eq!(rows_again, rows);
    assert_eq!(
        stub.count(),
        fetched,
        "read from the store, not fetched again"
    );
}

//! `roofs=inferred` over HTTP (docs/extensions.md section 4): Kirchfeld's untagged roofs take the
//! class the roof prior learned from its tagged ones, in scenes, their figures, XYZ tiles and 3D
//! Tiles, with the source and probability in each building's metadata; over the `--osm` files
//! one prior learns from every building, over data tiles one per data tile. Every figure is
//! exact: the prior is deterministic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh_core::geo::TileCoord;
use citymesh_core::osm::{BuildingRecord, OsmId, read_buildings};
use citymesh_core::roof_prior::RoofPrior;
use common::{app_with, data_dir, dem_dir, get, kirchfeld_app, osm_bytes};

const KIRCHFELD: &str = "8.3877,49.0390,8.4039,49.0640";

fn kirchfeld_prior() -> RoofPrior {
    let records = read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    RoofPrior::fit(&refs)
}

/// Checks every row of a GLB against the prior: a building whose roof was inferred carries the
/// prior's class and probability (to the 4 digits the tag keeps); answers how many were.
fn check_rows(glb: &[u8], prior: &RoofPrior) -> usize {
    let mut inferred = 0;
    for row in common::decode::feature_rows(glb) {
        let id: i64 = row["osm_id"].as_str().unwrap().parse().unwrap();
        let id = if row["osm_type"] == "way" {
            OsmId::Way(id)
        } else {
            OsmId::Relation(id)
        };
        if row["roof_source"] != "inferred" {
            continue;
        }
        inferred += 1;
        let (class, p) = prior.prediction(&id).unwrap();
        assert_eq!(row["roof_shape"], class.name(), "{id}");
        let written: f32 = row["roof_probability"].as_str().unwrap().parse().unwrap();
        assert!((written - p).abs() < 1e-4, "{id}: {written} against {p}");
        assert!(p >= 0.5);
    }
    inferred
}

#[tokio::test]
async fn kirchfelds_untagged_roofs_take_the_prior_of_its_files() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    let prior = kirchfeld_prior();

    // The figures: 2,359 of the 2,398 untagged buildings (outside groups with parts) get the
    // prior's class, 39 stay flat below the threshold; flat roofs fall from 90.3 % to 33.1 %.
    let osm = get(&app, &format!("/scene/stats?bbox={KIRCHFELD}"))
        .await
        .json();
    let inferred = get(
        &app,
        &format!("/scene/stats?bbox={KIRCHFELD}&roofs=inferred"),
    )
    .await
    .json();
    assert_eq!(inferred["roofs"], "inferred");
    let figures = &inferred["inferred_roofs"];
    assert_eq!(
        (
            &figures["inferred"],
            &figures["uncertain"],
            &figures["not_inferred"]
        ),
        (&2359.into(), &39.into(), &0.into())
    );
    let priors = figures["priors"].as_array().unwrap();
    assert_eq!(priors.len(), 1);
    assert_eq!(priors[0]["scope"], "all");
    assert_eq!(priors[0]["identity"], prior.report.identity.as_str());
    assert_eq!(priors[0]["tagged"], 572);
    assert_eq!(
        priors[0]["confusion"],
        serde_json::json!([[289, 3, 2], [3, 266, 1], [0, 6, 2]])
    );
    assert_eq!(inferred["buildings"]["roof_shape_inferred"], 2359);
    assert_eq!(
        inferred["buildings"]["roof_shapes"],
        serde_json::json!({"flat": 999, "gabled": 1983, "gambrel": 1, "hipped": 20,
            "pyramidal": 3, "quadruple_saltbox": 1, "skillion": 11})
    );
    let percent = |v: &serde_json::Value| (v.as_f64().unwrap() * 100.0).round() / 100.0;
    assert_eq!(percent(&osm["flat_roof_percent"]), 90.32);
    assert_eq!(percent(&inferred["flat_roof_percent"]), 33.1);
    assert_eq!(osm["inferred_roofs"], serde_json::Value::Null);
    assert_eq!(osm["buildings"]["roof_shape_inferred"], 0);
    assert_eq!(
        inferred["buildings"]["generated"],
        osm["buildings"]["generated"]
    );
    assert_eq!(
        inferred["buildings"]["roof_shape_from_tag"],
        osm["buildings"]["roof_shape_from_tag"]
    );

    // A tile: other bytes and ETag than with tags alone, and each inferred roof says so.
    let t = TileCoord::containing(16, 8.3955, 49.0525);
    let uri = format!("/tiles/16/{}/{}.glb", t.x, t.y);
    let plain = get(&app, &uri).await;
    let with_prior = get(&app, &format!("{uri}?roofs=inferred")).await;
    assert_eq!(with_prior.status, StatusCode::OK);
    common::assert_valid_glb(&with_prior.body);
    assert_ne!(plain.header("etag"), with_prior.header("etag"));
    let n = check_rows(&with_prior.body, &prior);
    assert!(n > 50, "{n} inferred roofs in the tile");
    assert_eq!(
        with_prior.header("x-citymesh-roofs"),
        format!("inferred, {n}")
    );
    assert_eq!(check_rows(&plain.body, &prior), 0);
    let again = get(&app, &format!("{uri}?roofs=inferred")).await;
    assert_eq!(again.header("x-citymesh-cache"), "hit");
    assert_eq!(again.header("etag"), with_prior.header("etag"));

    // 3D Tiles: the tileset passes the choice to its content and subtree, whose leaves carry
    // the inferred roofs.
    let tileset = get(
        &app,
        &format!("/3dtiles/tileset.json?bbox={KIRCHFELD}&roofs=inferred&tiling=implicit"),
    )
    .await
    .json();
    let content = tileset["root"]["content"]["uri"].as_str().unwrap();
    let subtrees = tileset["root"]["implicitTiling"]["subtrees"]["uri"]
        .as_str()
        .unwrap();
    assert!(content.ends_with(".glb?roofs=inferred"), "{content}");
    assert!(subtrees.ends_with(".subtree?roofs=inferred"), "{subtrees}");
    let subtree = get(
        &app,
        &format!("/3dtiles/area/{KIRCHFELD}/subtrees/0/0/0.subtree?roofs=inferred"),
    )
    .await;
    assert_eq!(subtree.status, StatusCode::OK);
    let root: citymesh_core::geo::GeoBbox = KIRCHFELD.parse().unwrap();
    let leaf = citymesh_core::tiles3d::ImplicitLayout::leaf_level_of(&root);
    let tile = citymesh_core::geo::ImplicitTile::containing(&root, leaf, 8.3955, 49.0525);
    let leaf_uri = format!(
        "/3dtiles/area/{KIRCHFELD}/content/{}/{}/{}.glb?roofs=inferred",
        tile.level, tile.x, tile.y
    );
    let leaf_content = get(&app, &leaf_uri).await;
    assert_eq!(leaf_content.status, StatusCode::OK, "{leaf_uri}");
    assert!(check_rows(&leaf_content.body, &prior) > 0);
}

#[tokio::test]
async fn over_data_tiles_each_data_tile_has_its_prior() {
    let db = tempfile::tempdir().unwrap();
    let file = db.path().join("c.sqlite");
    let pbf = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    citymesh::commands::import::import(&[pbf], file.to_str().unwrap(), true)
        .await
        .unwrap();
    let app = app_with(&dem_dir(), &file, &["--offline"]).await;
    let stats = get(
        &app,
        &format!("/scene/stats?bbox={KIRCHFELD}&roofs=inferred"),
    )
    .await
    .json();
    // One prior per z14 data tile the buildings' first nodes fall in, each from that tile's
    // buildings: where a tile has too few tags (here one), its prior abstains and its roofs stay
    // flat.
    let figures = &stats["inferred_roofs"];
    let priors: Vec<(String, u64, u64, Option<u64>, bool)> = figures["priors"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let correct = p["confusion"]
                .as_array()
                .map(|rows| (0..3).map(|i| rows[i][i].as_u64().unwrap()).sum::<u64>());
            (
                p["scope"].as_str().unwrap().to_owned(),
                p["buildings"].as_u64().unwrap(),
                p["tagged"].as_u64().unwrap(),
                correct,
                p["abstained"].is_null(),
            )
        })
        .collect();
    assert_eq!(
        priors,
        [
            ("14/8573/5622".to_owned(), 177, 1, None, false),
            ("14/8573/5623".to_owned(), 564, 62, Some(52), true),
            ("14/8574/5622".to_owned(), 858, 482, Some(477), true),
            ("14/8574/5623".to_owned(), 1460, 35, Some(33), true),
        ]
    );
    assert_eq!(
        (
            &figures["inferred"],
            &figures["uncertain"],
            &figures["not_inferred"]
        ),
        (&2197.into(), &35.into(), &166.into())
    );
    assert_eq!(stats["buildings"]["roof_shape_inferred"], 2197);
}

/// Fits of roof priors so far: misses of the priors' cache, from `/metrics`.
async fn prior_fits(app: &axum::Router) -> u64 {
    let metrics = get(app, "/metrics").await.text();
    metrics
        .lines()
        .find(|l| {
            l.starts_with("citymesh_cache_requests_total{")
                && l.contains("level=\"roof_prior\"")
                && l.contains("result=\"miss\"")
        })
        .map_or(0, |l| l.rsplit(' ').next().unwrap().parse().unwrap())
}

/// Round 3, item 6: with `--memory-mb 6` the priors' share (2 %, 126 KB) could not keep
/// Kirchfeld's whole prior (144 KB), so every tile with `roofs=inferred`, cached or not, fitted
/// it again. The files' buildings are now cut into tiles whose priors each weigh at most a
/// quarter of the share, and a cached tile fits nothing.
#[tokio::test]
async fn with_little_memory_priors_are_cut_to_fit_and_cached_tiles_fit_nothing() {
    let db = tempfile::tempdir().unwrap();
    let pbf = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let app = app_with(
        &dem_dir(),
        &db.path().join("c.sqlite"),
        &["--osm", pbf.to_str().unwrap(), "--memory-mb", "6"],
    )
    .await;
    let t = TileCoord::containing(18, 8.3955, 49.0525);
    let uri = format!("/tiles/18/{}/{}.glb?roofs=inferred", t.x, t.y);
    let first = get(&app, &uri).await;
    assert_eq!(first.status, StatusCode::OK);
    let fitted = prior_fits(&app).await;
    assert!(fitted >= 1, "{fitted} fits");
    let again = get(&app, &uri).await;
    assert_eq!(again.header("x-citymesh-cache"), "hit");
    assert_eq!(again.header("etag"), first.header("etag"));
    assert_eq!(
        prior_fits(&app).await,
        fitted,
        "a cached tile fitted its priors again"
    );
    // The scopes are tiles of one zoom from the data tiles' (14) on.
    let stats = get(
        &app,
        &format!("/scene/stats?bbox={KIRCHFELD}&roofs=inferred"),
    )
    .await
    .json();
    let figures = &stats["inferred_roofs"];
    let priors = figures["priors"].as_array().unwrap();
    let zooms: std::collections::BTreeSet<u64> = priors
        .iter()
        .map(|p| {
            let scope = p["scope"].as_str().unwrap();
            scope.split('/').next().unwrap().parse().unwrap()
        })
        .collect();
    assert_eq!(zooms.len(), 1, "{zooms:?}");
    let zoom = *zooms.first().unwrap();
    assert!((14..=18).contains(&zoom), "{zoom}");
    assert!(priors.len() > 1, "{} priors", priors.len());
    eprintln!(
        "--memory-mb 6: {} priors at zoom {zoom}; {} inferred, {} uncertain, {} not inferred",
        priors.len(),
        figures["inferred"],
        figures["uncertain"],
        figures["not_inferred"]
    );
}

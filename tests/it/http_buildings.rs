//! Buildings served over HTTP from local OSM files: real buildings on real terrain in
//! `/scene.glb` and `/tiles`, the figures in `/scene/stats` and the response headers, every
//! real file's scene through the Khronos glTF Validator, and each building in exactly one tile.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;
use common::{app_with, assert_valid_glb, data_dir, dem_dir, get, osm_bytes};

fn osm(name: &str) -> String {
    data_dir().join("osm").join(name).display().to_string()
}

async fn kirchfeld_app(db: &tempfile::TempDir) -> axum::Router {
    let file = osm("karlsruhe-kirchfeld.osm.pbf");
    app_with(&dem_dir(), &db.path().join("c.sqlite"), &["--osm", &file]).await
}

#[tokio::test]
async fn scene_shows_real_buildings_on_real_terrain() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    let health = get(&app, "/health").await.json();
    assert_eq!(health["buildings"], 2995 + 31);

    let glb = get(&app, "/scene.glb?bbox=8.39,49.04,8.41,49.06").await;
    assert_eq!(glb.status, StatusCode::OK);
    assert_valid_glb(&glb.body);
    assert_eq!(glb.header("x-citymesh-ground"), "dem");
    assert_eq!(glb.header("x-citymesh-buildings-skipped"), "0");
    let generated: usize = glb.header("x-citymesh-buildings").parse().unwrap();

    let stats = get(&app, "/scene/stats?bbox=8.39,49.04,8.41,49.06").await;
    assert_eq!(stats.status, StatusCode::OK);
    let s = stats.json();
    // The same scene: the same figures as the GLB's headers.
    assert_eq!(s["buildings"]["generated"], generated);
    assert_eq!(s["glb_bytes"], glb.body.len());
    assert_eq!(
        s["triangles"].to_string(),
        glb.header("x-citymesh-triangles")
    );
    assert_eq!(s["vertices"].to_string(), glb.header("x-citymesh-vertices"));
    assert_eq!(
        format!("{:.1}", s["flat_roof_percent"].as_f64().unwrap()),
        glb.header("x-citymesh-flat-roofs-percent")
    );

    // Counted independently: records with any node in the box (the box cuts the rest away).
    let b = read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let bbox = GeoBbox::new(8.39, 49.04, 8.41, 49.06).unwrap();
    let inside = b
        .buildings
        .iter()
        .filter(|r| {
            r.outers
                .iter()
                .flat_map(|o| &o.nodes)
                .all(|n| bbox.contains(n.lon, n.lat))
        })
        .count();
    let touching = b
        .buildings
        .iter()
        .filter(|r| {
            r.outers
                .iter()
                .flat_map(|o| &o.nodes)
                .any(|n| bbox.contains(n.lon, n.lat))
        })
        .count();
    let covered = s["buildings"]["outlines_covered_by_parts"]
        .as_u64()
        .unwrap() as usize;
    assert!(
        generated + covered >= inside && generated <= touching,
        "{generated} generated; {inside} inside, {touching} touching"
    );
    let shapes = &s["buildings"]["roof_shapes"];
    let total: u64 = shapes
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(total as usize, generated);
    assert_eq!(
        s["buildings"]["roof_shape_from_tag"].as_u64().unwrap()
            + s["buildings"]["roof_shape_default"].as_u64().unwrap()
            + s["buildings"]["roof_shape_unsupported"].as_u64().unwrap(),
        generated as u64
    );
    assert!(s["ground"]["missing_dem"].as_array().unwrap().is_empty());
}

#[tokio::test]
async fn stats_refuse_a_bad_box_like_the_scene() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    let a = get(&app, "/scene/stats?bbox=8.41,49.04,8.39,49.06").await;
    assert_eq!(a.status, StatusCode::BAD_REQUEST);
    assert_eq!(a.json()["error"], "invalid_bbox");
    let a = get(&app, "/scene/stats").await;
    assert_eq!(a.status, StatusCode::BAD_REQUEST);
    assert_eq!(a.json()["error"], "missing_bbox");
}

#[tokio::test]
async fn every_building_lands_in_exactly_one_tile() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    // All z15 tiles over the buildings' extent (8.3877,49.0390 - 8.4039,49.0640).
    let (a, b) = (
        TileCoord::containing(15, 8.3877, 49.0640),
        TileCoord::containing(15, 8.4039, 49.0390),
    );
    let mut total = 0;
    let mut with_buildings = 0;
    for x in a.x..=b.x {
        for y in a.y..=b.y {
            let t = get(&app, &format!("/tiles/15/{x}/{y}.glb")).await;
            assert_eq!(t.status, StatusCode::OK);
            let n: usize = t.header("x-citymesh-buildings").parse().unwrap();
            if n > 0 {
                with_buildings += 1;
                assert_valid_glb(&t.body);
            }
            total += n;
        }
    }
    assert!(with_buildings >= 2, "the area spans several tiles");
    // Every record is generated once across the tiles (outlines covered by parts excepted).
    assert_eq!(total, 3018);
}

#[test]
fn every_real_file_gives_a_valid_glb() {
    for (file, dem) in [
        ("karlsruhe-kirchfeld.osm.pbf", Some("N49E008.hgt")),
        ("karlsruhe-kit-nord.osm.pbf", Some("N49E008.hgt")),
        ("tram-junction.osm.pbf", Some("N49E008.hgt")),
        ("nuremberg-laufamholz.osm", Some("N49E011.hgt")),
        ("san-francisco.overpass.json.gz", None),
    ] {
        let set = BuildingSet::new(read_buildings(&osm_bytes(file)).unwrap().buildings);
        let model = match dem {
            Some(name) => {
                let (lat, lon) = citymesh_core::terrain::parse_hgt_name(name).unwrap();
                let bytes = std::fs::read(dem_dir().join(name)).unwrap();
                ElevationModel::new(vec![std::sync::Arc::new(
                    citymesh_core::terrain::HgtTile::from_bytes(lat, lon, &bytes).unwrap(),
                )])
            }
            None => ElevationModel::default(),
        };
        let scene = Scene::new(&model, &set.extent().unwrap(), &set.groups(), Border::Whole);
        let report = common::validate_glb(&scene.to_glb());
        assert_eq!(report["errors"], 0, "{file}: {report}");
        assert_eq!(report["warnings"], 0, "{file}: {report}");
    }
}

#[tokio::test]
async fn a_gzipped_overpass_response_is_served_on_flat_fallback_ground() {
    let db = tempfile::tempdir().unwrap();
    let file = osm("san-francisco.overpass.json.gz");
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &["--osm", &file]).await;
    let s = get(&app, "/scene/stats?bbox=-122.47,37.76,-122.46,37.77")
        .await
        .json();
    assert!(s["buildings"]["generated"].as_u64().unwrap() > 100, "{s}");
    assert_eq!(s["ground"]["missing_dem"][0], "N37W123");
    let glb = get(&app, "/scene.glb?bbox=-122.47,37.76,-122.46,37.77").await;
    assert_eq!(
        glb.header("x-citymesh-ground"),
        "flat-fallback; missing=N37W123"
    );
}

#[tokio::test]
async fn a_file_that_is_not_osm_stops_start_up_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.osm");
    std::fs::write(&bad, b"this is not OSM").unwrap();
    let args = <citymesh::cli::ServeArgs as clap::Parser>::parse_from([
        "serve",
        "--cache-db",
        ":memory:",
        "--osm",
        bad.to_str().unwrap(),
    ]);
    let err = citymesh::server::build_state(&args).await.err().unwrap();
    let text = format!("{err:#}");
    assert!(
        text.contains("bad.osm") && text.contains("OSM PBF, OSM XML or Overpass JSON"),
        "{text}"
    );
}

/// The row of `way` in a GLB's property table.
fn row_of(glb: &[u8], way: &str) -> serde_json::Map<String, serde_json::Value> {
    common::decode::feature_rows(glb)
        .into_iter()
        .find(|r| r["osm_type"] == "way" && r["osm_id"] == way)
        .unwrap_or_else(|| panic!("no row for way/{way}"))
}

#[tokio::test]
async fn tags_all_carries_every_osm_tag_of_a_building_as_one_json_object() {
    let db = tempfile::tempdir().unwrap();
    let state = common::kirchfeld_state(&db).await;
    common::world_ready(&state).await;
    let app = common::app_of(state);
    // Way 142104398's tags as OpenStreetMap has them (read with pyosmium).
    let want = serde_json::json!({
        "addr:city": "Karlsruhe", "addr:country": "DE", "addr:housenumber": "10",
        "addr:postcode": "76149", "addr:street": "An der Vogelhardt", "addr:suburb": "Neureut",
        "brand": "PLAZA Hotelgroup GmbH", "building": "hotel", "building:levels": "4",
        "email": "karlsruhe2@plazahotels.de", "internet_access": "wlan",
        "internet_access:fee": "no", "name": "PLAZA INN Karlsruhe Nord",
        "old_name": "Hotel Newton Karlsruhe", "phone": "+49 721 78194800", "roof:levels": "0",
        "roof:material": "grass", "roof:shape": "flat", "rooms": "83",
        "source:geometry": "Maps4BW, LGL, www.lgl-bw.de", "stars": "3", "start_date": "1994",
        "tourism": "hotel", "website": "https://plazahotels.de/hotel-karlsruhe-nord/",
    });
    let (lon, lat) = (8.39366, 49.04397);
    let t16 = TileCoord::containing(16, lon, lat);
    let t15 = TileCoord::containing(15, lon, lat);
    for (plain, tagged) in [
        (
            format!("/tiles/16/{}/{}.glb", t16.x, t16.y),
            format!("/tiles/16/{}/{}.glb?tags=all", t16.x, t16.y),
        ),
        (
            format!("/3dtiles/world/15/{}/{}.glb", t15.x, t15.y),
            format!("/3dtiles/world/15/{}/{}.glb?tags=all", t15.x, t15.y),
        ),
    ] {
        let without = get(&app, &plain).await;
        let with = get(&app, &tagged).await;
        assert_eq!(with.status, StatusCode::OK, "{tagged}: {}", with.text());
        assert_valid_glb(&with.body);
        // Without the option the column is not there at all (it costs nothing).
        assert!(
            !row_of(&without.body, "142104398").contains_key("osm_tags"),
            "{plain}"
        );
        let row = row_of(&with.body, "142104398");
        let tags: serde_json::Value =
            serde_json::from_str(row["osm_tags"].as_str().unwrap()).unwrap();
        assert_eq!(tags, want, "{tagged}");
        // Every building carries it, and the named properties are unchanged.
        for r in common::decode::feature_rows(&with.body) {
            assert!(r["osm_tags"].as_str().unwrap().starts_with('{'), "{tagged}");
        }
        assert_eq!(row["height"], "12");
        assert_ne!(without.header("etag"), with.header("etag"), "{tagged}");
    }
    // The world tileset passes the option on to its content.
    let tree = get(&app, "/3dtiles/world/12/2143/1405.json?tags=all").await;
    assert!(tree.text().contains(".glb?tags=all"), "{}", tree.text());
    let bad = get(&app, "/3dtiles/world/15/17148/11246.glb?tags=some").await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
    assert_eq!(bad.json()["error"], "invalid_query");
}

#[tokio::test]
async fn a_building_carries_its_osm_identity_and_tags_in_every_kind_of_glb() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    // The PLAZA INN hotel (way 142104398): 4 levels of 3 m, a flat roof of grass.
    let want: serde_json::Map<String, serde_json::Value> = serde_json::json!({
        "osm_type": "way", "osm_id": "142104398", "building": "hotel",
        "name": "PLAZA INN Karlsruhe Nord", "address": "An der Vogelhardt 10, 76149 Karlsruhe",
        "height": "12", "min_height": "0", "levels": "4", "roof_shape": "flat",
        "roof_source": "tag", "roof_probability": "-1", "wall_colour": "#e8e0d0",
        "roof_colour": "#6a8a48",
        // What Cesium OSM Buildings' styles and apps read (the centre is checked below).
        "elementId": "142104398", "elementType": "way", "cesium_estimatedHeight": "12",
    })
    .as_object()
    .unwrap()
    .clone();
    let (lon, lat) = (8.39366, 49.04397);
    let z = 16u8;
    let tile = TileCoord::containing(z, lon, lat);
    let uris = [
        format!("/tiles/{z}/{}/{}.glb", tile.x, tile.y),
        format!("/tiles/{z}/{}/{}.glb?encoding=meshopt", tile.x, tile.y),
        "/scene.glb?bbox=8.3930,49.0433,8.3943,49.0446".to_owned(),
    ];
    for uri in uris {
        let answer = get(&app, &uri).await;
        assert_eq!(answer.status, StatusCode::OK, "{uri}");
        let mut row = row_of(&answer.body, "142104398");
        // The centre of the way's bounding box, as pyosmium reads its six nodes: longitude
        // 8.3935053 to 8.3938173, latitude 49.0437411 to 49.0442034.
        for (key, want) in [
            ("cesium_longitude", 8.393_661_3),
            ("cesium_latitude", 49.043_972_25),
        ] {
            let got: f64 = row.remove(key).unwrap().as_str().unwrap().parse().unwrap();
            assert!((got - want).abs() < 1e-9, "{key} {got} in {uri}");
        }
        // Its quality record: a closed solid, its floor drawn as its outline leaves it.
        let quality: Vec<_> = ["closed", "strict_manifold", "floor_area", "outline_area"]
            .map(|k| row.remove(k).unwrap_or_else(|| panic!("{k} in {uri}")))
            .into();
        assert_eq!(quality[0], "true", "{uri}");
        assert_eq!(quality[2], quality[3], "{uri}");
        let floor: f64 = quality[2].as_str().unwrap().parse().unwrap();
        assert!(floor > 100.0, "{uri}: {floor}");
        // roof_probability is left out when no building in the file was classified.
        let mut expected = want.clone();
        if !row.contains_key("roof_probability") {
            expected.remove("roof_probability");
        }
        assert_eq!(row, expected, "{uri}");
    }
}

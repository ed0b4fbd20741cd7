//! Procedural and user-defined scenes over HTTP: determinism, layouts and roof shapes by weight,
//! the GeoJSON round trip through `POST /scene.glb`, every invalid upload with its status and
//! message, and the demo city a server with no data serves.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use common::{Answer, app_with, assert_valid_glb, get};
use http_body_util::BodyExt;
use serde_json::{Value, json};
use std::collections::BTreeSet;
use tower::ServiceExt;

async fn app() -> (axum::Router, tempfile::TempDir) {
    let db = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let app = app_with(empty.path(), &db.path().join("c.sqlite"), &[]).await;
    (app, db)
}

async fn post(app: &axum::Router, content_type: &str, body: Vec<u8>) -> Answer {
    let r = app
        .clone()
        .oneshot(
            Request::post("/scene.glb")
                .header("content-type", content_type)
                .body(Body::from(body))
                .unwrap(),
        )
        .await
        .unwrap();
    let status = r.status();
    let headers = r.headers().clone();
    let body = r.into_body().collect().await.unwrap().to_bytes().to_vec();
    Answer {
        status,
        headers,
        body,
    }
}

fn features(geojson: &[u8]) -> Vec<Value> {
    let doc: Value = serde_json::from_slice(geojson).unwrap();
    doc["features"].as_array().unwrap().clone()
}

fn values(features: &[Value], key: &str) -> BTreeSet<String> {
    features
        .iter()
        .filter_map(|f| f["properties"][key].as_str().map(str::to_owned))
        .collect()
}

const Q: &str = "seed=7&size=600,400&complexity=5";

#[tokio::test]
async fn the_same_seed_gives_the_same_bytes_and_another_seed_another_city() {
    let (app, _db) = app().await;
    let a = get(&app, &format!("/procedural.geojson?{Q}")).await;
    assert_eq!(a.status, StatusCode::OK);
    assert_eq!(a.header("content-type"), "application/geo+json");
    let b = get(&app, &format!("/procedural.geojson?{Q}")).await;
    assert!(a.body == b.body);
    let g1 = get(&app, &format!("/procedural.glb?{Q}")).await;
    let g2 = get(&app, &format!("/procedural.glb?{Q}")).await;
    assert_eq!(g1.status, StatusCode::OK);
    assert!(g1.body == g2.body);
    assert_valid_glb(&g1.body);
    let other = get(&app, "/procedural.geojson?seed=8&size=600,400&complexity=5").await;
    assert!(other.body != a.body);
    let other_glb = get(&app, "/procedural.glb?seed=8&size=600,400&complexity=5").await;
    assert!(other_glb.body != g1.body);
}

#[tokio::test]
async fn each_layout_appears_exactly_when_it_has_weight() {
    let (app, _db) = app().await;
    let all = features(
        &get(&app, "/procedural.geojson?seed=3&complexity=6")
            .await
            .body,
    );
    let every: BTreeSet<String> = ["detached", "row", "perimeter", "tower", "industrial"]
        .map(str::to_owned)
        .into();
    assert_eq!(values(&all, "citymesh:layout"), every);
    for layout in ["detached", "row", "perimeter", "tower", "industrial"] {
        let f = features(
            &get(
                &app,
                &format!("/procedural.geojson?seed=3&complexity=6&layouts={layout}:1"),
            )
            .await
            .body,
        );
        assert!(!f.is_empty(), "{layout}");
        assert_eq!(
            values(&f, "citymesh:layout"),
            [layout.to_owned()].into(),
            "{layout}"
        );
    }
    // Two layouts weighted, the others 0.
    let f = features(
        &get(
            &app,
            "/procedural.geojson?seed=3&complexity=6&layouts=row:1,tower:1",
        )
        .await
        .body,
    );
    assert_eq!(
        values(&f, "citymesh:layout"),
        ["row".to_owned(), "tower".to_owned()].into()
    );
    // What each layout is made of.
    let f = features(
        &get(
            &app,
            "/procedural.geojson?seed=3&complexity=6&layouts=tower:1",
        )
        .await
        .body,
    );
    assert!(f.iter().any(|x| x["properties"]["building:part"] == "yes"));
    assert!(
        f.iter()
            .any(|x| x["properties"].get("min_height").is_some())
    );
    let f = features(
        &get(
            &app,
            "/procedural.geojson?seed=3&complexity=6&layouts=perimeter:1",
        )
        .await
        .body,
    );
    assert!(
        f.iter()
            .all(|x| !x["geometry"]["coordinates"].as_array().unwrap().is_empty())
    );
    assert!(
        f.iter()
            .any(|x| x["geometry"]["coordinates"].as_array().unwrap().len() == 2)
    );
}

#[tokio::test]
async fn each_roof_shape_appears_exactly_when_it_has_weight() {
    let (app, _db) = app().await;
    let shapes = [
        "flat",
        "gabled",
        "hipped",
        "pyramidal",
        "skillion",
        "half-hipped",
        "gambrel",
        "mansard",
    ];
    // Detached houses take their roofs from the weights.
    let all = features(
        &get(
            &app,
            "/procedural.geojson?seed=5&complexity=6&layouts=detached:1",
        )
        .await
        .body,
    );
    assert_eq!(values(&all, "roof:shape"), shapes.map(str::to_owned).into());
    for shape in shapes {
        let f = features(
            &get(
                &app,
                &format!("/procedural.geojson?seed=5&complexity=6&layouts=detached:1,row:1,perimeter:1&roofs={shape}:1"),
            )
            .await
            .body,
        );
        assert_eq!(
            values(&f, "roof:shape"),
            [shape.to_owned()].into(),
            "{shape}"
        );
    }
    // Towers and halls force flat roofs whatever the weights say.
    let f = features(
        &get(
            &app,
            "/procedural.geojson?seed=5&complexity=6&layouts=tower:1,industrial:1&roofs=gabled:1",
        )
        .await
        .body,
    );
    assert_eq!(values(&f, "roof:shape"), ["flat".to_owned()].into());
}

#[tokio::test]
async fn posting_the_procedural_geojson_gives_the_procedural_mesh() {
    let (app, _db) = app().await;
    let q = "seed=11&size=700,500&complexity=6";
    let geojson = get(&app, &format!("/procedural.geojson?{q}")).await.body;
    let expected = get(&app, &format!("/procedural.glb?{q}")).await;
    let posted = post(&app, "application/geo+json", geojson).await;
    assert_eq!(posted.status, StatusCode::OK);
    assert_eq!(
        posted.header("x-citymesh-buildings"),
        expected.header("x-citymesh-buildings")
    );
    assert!(posted.body == expected.body, "the meshes differ");
}

#[tokio::test]
async fn every_simple_3d_buildings_roof_shape_is_drawn_as_itself() {
    let (app, _db) = app().await;
    // Each value as OpenStreetMap writes it, with the shape citymesh draws for it.
    let shapes = [
        ("flat", "flat"),
        ("gabled", "gabled"),
        ("hipped", "hipped"),
        ("pyramidal", "pyramidal"),
        ("skillion", "skillion"),
        ("half-hipped", "half-hipped"),
        ("gambrel", "gambrel"),
        ("mansard", "mansard"),
        ("saltbox", "saltbox"),
        ("double_saltbox", "double_saltbox"),
        ("quadruple_saltbox", "quadruple_saltbox"),
        ("side_hipped", "side_hipped"),
        ("side_half-hipped", "side_half-hipped"),
        ("sawtooth", "sawtooth"),
        ("crosspitched", "crosspitched"),
        ("round", "round"),
        ("dome", "dome"),
        ("onion", "onion"),
        ("cone", "cone"),
        ("frustum", "frustum"),
        ("frustrum", "frustum"),
        // Drawn by their parts: the outline is flat.
        ("many", "flat"),
        ("complex", "flat"),
    ];
    // 20 m x 12 m houses in a row, 12 m tall with 4 m of roof, on flat ground.
    let features: Vec<Value> = shapes
        .iter()
        .enumerate()
        .map(|(i, (tag, _))| {
            let w = 8.4 + i as f64 * 0.0004;
            let (e, n) = (w + 20.0 / 73_000.0, 49.01 + 12.0 / 111_200.0);
            json!({"type": "Feature",
                "properties": {"height": 12, "roof:height": 4, "roof:shape": tag},
                "geometry": {"type": "Polygon", "coordinates": [[[w, 49.01], [e, 49.01], [e, n], [w, n], [w, 49.01]]]}})
        })
        .collect();
    let a = post(&app, "application/geo+json", collection(features)).await;
    assert_eq!(
        a.status,
        StatusCode::OK,
        "{}",
        String::from_utf8_lossy(&a.body)
    );
    assert_valid_glb(&a.body);
    assert_eq!(a.header("x-citymesh-buildings"), shapes.len().to_string());
    // Every shape came from its tag: none was unsupported (drawn flat instead).
    assert_eq!(
        a.header("x-citymesh-roof-shapes-from-tags-percent"),
        "100.0"
    );
    let rows = common::decode::feature_rows(&a.body);
    let drawn: Vec<&str> = rows
        .iter()
        .map(|r| r["roof_shape"].as_str().unwrap())
        .collect();
    let want: Vec<&str> = shapes.iter().map(|(_, s)| *s).collect();
    assert_eq!(drawn, want);
    assert!(rows.iter().all(|r| r["roof_source"] == "tag"));
    // Each roof reaches the top, 12 m over the ground (0 m here), and a pitched one comes down
    // to its eaves, 8 m, somewhere.
    let triangles = common::decode::triangles(&a.body);
    for (i, (tag, shape)) in shapes.iter().enumerate() {
        let heights: Vec<f64> = triangles
            .iter()
            .filter(|t| t.material == "roof" && t.feature == Some(i as u32))
            .flat_map(|t| t.corners.map(|c| c[1]))
            .collect();
        let top = heights.iter().copied().fold(f64::MIN, f64::max);
        let low = heights.iter().copied().fold(f64::MAX, f64::min);
        assert!((top - 12.0).abs() < 1e-3, "{tag}: top {top}");
        let eaves = if *shape == "flat" { 12.0 } else { 8.0 };
        assert!((low - eaves).abs() < 1e-3, "{tag}: lowest roof point {low}");
    }
}

/// A valid single building, to break one piece at a time.
fn building() -> Value {
    json!({"type": "Feature", "properties": {"height": 10, "roof:shape": "gabled"},
        "geometry": {"type": "Polygon", "coordinates": [[[8.4, 49.01], [8.4002, 49.01], [8.4002, 49.0101], [8.4, 49.0101], [8.4, 49.01]]]}})
}

fn collection(features: Vec<Value>) -> Vec<u8> {
    serde_json::to_vec(&json!({"type": "FeatureCollection", "features": features})).unwrap()
}

#[tokio::test]
async fn a_posted_collection_with_a_courtyard_builds_on_the_dem() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&common::dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let mut b = building();
    b["geometry"] = json!({"type": "MultiPolygon", "coordinates": [[
        [[8.41, 49.01], [8.411, 49.01], [8.411, 49.011], [8.41, 49.011], [8.41, 49.01]],
        [[8.4103, 49.0103], [8.4103, 49.0107], [8.4107, 49.0107], [8.4107, 49.0103], [8.4103, 49.0103]]
    ]]});
    let a = post(&app, "application/json", collection(vec![b, building()])).await;
    assert_eq!(
        a.status,
        StatusCode::OK,
        "{}",
        String::from_utf8_lossy(&a.body)
    );
    assert_eq!(a.header("x-citymesh-buildings"), "2");
    assert_eq!(a.header("x-citymesh-ground"), "dem");
    assert_valid_glb(&a.body);
}

/// An upload case: name, content type, body, status, error code, feature index, message part.
type Case<'a> = (
    &'a str,
    &'a str,
    Vec<u8>,
    StatusCode,
    &'a str,
    Option<u64>,
    &'a str,
);

#[tokio::test]
async fn every_invalid_upload_gets_its_status_and_says_what_to_fix() {
    let db = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let app = app_with(
        empty.path(),
        &db.path().join("c.sqlite"),
        &[
            "--max-upload-mb",
            "1",
            "--max-features",
            "50",
            "--max-vertices",
            "400",
        ],
    )
    .await;
    let with = |f: &dyn Fn(&mut Value)| {
        let mut b = building();
        f(&mut b);
        collection(vec![building(), b])
    };
    let big_ring: Vec<Value> = (0..=450)
        .map(|i| {
            let a = f64::from(i) / 450.0 * std::f64::consts::TAU;
            json!([8.4 + 0.001 * a.cos(), 49.01 + 0.001 * a.sin()])
        })
        .collect();
    let cases: Vec<Case> = vec![
        (
            "not JSON",
            "application/json",
            b"{not json".to_vec(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "not_json",
            None,
            "not JSON",
        ),
        (
            "wrong media type",
            "text/plain",
            collection(vec![building()]),
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported_media_type",
            None,
            "application/geo+json",
        ),
        (
            "not a FeatureCollection",
            "application/json",
            serde_json::to_vec(&building()).unwrap(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            None,
            "must be a GeoJSON FeatureCollection",
        ),
        (
            "a Point",
            "application/json",
            with(&|b| b["geometry"] = json!({"type": "Point", "coordinates": [8.4, 49.0]})),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].geometry.type: is \"Point\"; buildings must be Polygon or MultiPolygon",
        ),
        (
            "an unclosed ring",
            "application/json",
            with(&|b| {
                b["geometry"]["coordinates"][0]
                    .as_array_mut()
                    .unwrap()
                    .pop();
                b["geometry"]["coordinates"][0]
                    .as_array_mut()
                    .unwrap()
                    .push(json!([8.4, 49.00005]));
            }),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].geometry.coordinates[0]: is not closed",
        ),
        (
            "a self-intersecting ring",
            "application/json",
            with(&|b| {
                b["geometry"]["coordinates"] = json!([[
                    [8.4, 49.0],
                    [8.4002, 49.0001],
                    [8.4002, 49.0],
                    [8.4, 49.00004],
                    [8.4, 49.0]
                ]]);
            }),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].geometry.coordinates[0]: crosses itself",
        ),
        (
            "a latitude of 95",
            "application/json",
            with(&|b| b["geometry"]["coordinates"][0][2] = json!([8.4002, 95.0])),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].geometry.coordinates[0][2]: [8.4002, 95] is out of range",
        ),
        (
            "a height of 1e9",
            "application/json",
            with(&|b| b["properties"]["height"] = json!(1e9)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].properties.height: '1000000000.0' is not a length in metres from 0 to 1000",
        ),
        (
            "a NaN height",
            "application/json",
            with(&|b| b["properties"]["height"] = json!("NaN")),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].properties.height: 'NaN' is not a length",
        ),
        (
            "an unknown roof shape",
            "application/json",
            with(&|b| b["properties"]["roof:shape"] = json!("gabeld")),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].properties.roof:shape: 'gabeld' is not one of flat, gabled",
        ),
        (
            "min_height above height",
            "application/json",
            with(&|b| b["properties"]["min_height"] = json!(12)),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            Some(1),
            "features[1].properties.min_height: 12 is not below the height 10",
        ),
        (
            "too many features",
            "application/json",
            collection(vec![building(); 51]),
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            None,
            "51 features, more than the limit of 50",
        ),
        (
            "too many vertices",
            "application/json",
            with(&|b| b["geometry"]["coordinates"] = json!([big_ring.clone()])),
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            Some(1),
            "more than 400 positions",
        ),
        (
            "a body over the size limit",
            "application/json",
            vec![b' '; 1_100_000],
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            None,
            "over this server's limit of 1 MB",
        ),
        (
            "no features",
            "application/json",
            collection(vec![]),
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            None,
            "has no feature",
        ),
    ];
    for (name, content_type, body, status, code, feature, message) in cases {
        let a = post(&app, content_type, body).await;
        assert_eq!(
            a.status,
            status,
            "{name}: {}",
            String::from_utf8_lossy(&a.body)
        );
        let e = a.json();
        assert_eq!(e["error"], code, "{name}: {e}");
        assert_eq!(e["feature"].as_u64(), feature, "{name}: {e}");
        assert!(
            e["detail"].as_str().unwrap().contains(message),
            "{name}: {e}"
        );
    }
}

#[tokio::test]
async fn procedural_parameters_out_of_range_are_refused() {
    let db = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    let app = app_with(
        empty.path(),
        &db.path().join("c.sqlite"),
        &["--max-bbox-km2", "1"],
    )
    .await;
    for (query, message) in [
        ("size=10", "width must be between 50 and 5000 metres"),
        ("size=1000,x", "size '1000,x' must be W,H"),
        (
            "complexity=40",
            "complexity must be a whole number from 0 to 12",
        ),
        ("layouts=castle:1", "layouts: unknown 'castle'"),
        (
            "roofs=gabled:-1",
            "weight of 'gabled' must be a finite number >= 0",
        ),
        (
            "lat=89",
            "lon must be within -180..180 and lat within -85..85",
        ),
        ("size=1100", "more than this server's limit of 1 km²"),
        ("seed=abc", "seed"),
    ] {
        let a = get(&app, &format!("/procedural.glb?{query}")).await;
        assert_eq!(a.status, StatusCode::BAD_REQUEST, "{query}");
        let e = a.json();
        assert!(
            e["detail"].as_str().unwrap().contains(message),
            "{query}: {e}"
        );
    }
}

#[tokio::test]
async fn with_no_data_configured_the_server_shows_a_demo_city() {
    let db = tempfile::tempdir().unwrap();
    let empty = tempfile::tempdir().unwrap();
    // No --osm, no --overpass-url, no DEM files, nothing imported, not --offline.
    let args = <citymesh::cli::ServeArgs as clap::Parser>::parse_from([
        "serve",
        "--dem-dir",
        empty.path().to_str().unwrap(),
        "--cache-db",
        db.path().join("c.sqlite").to_str().unwrap(),
    ]);
    let state = citymesh::server::build_state(&args).await.unwrap();
    assert!(state.demo);
    let app = citymesh::app(state);
    let index = String::from_utf8(get(&app, "/").await.body).unwrap();
    assert!(index.contains("/procedural.glb"));
    // The demo city stands around Karlsruhe palace and is served like OSM data.
    let s = get(&app, "/scene/stats?bbox=8.400,49.010,8.409,49.017")
        .await
        .json();
    assert!(s["buildings"]["generated"].as_u64().unwrap() > 50, "{s}");
    let t = get(&app, "/tiles/16/34297/22502.glb").await;
    assert_eq!(t.status, StatusCode::OK);
    assert_eq!(t.header("x-citymesh-osm"), "files");
    assert!(t.header("x-citymesh-buildings").parse::<usize>().unwrap() > 0);
}

/// A named outline (metres, counter-clockwise) and the walls that close its wings.
type WingedOutline = (&'static str, Vec<[f64; 2]>, Vec<usize>);

/// An L, a T and a U, wings 6 m wide, each with the walls that close its wings (where a gabled
/// roof has its gables).
fn winged_outlines() -> [WingedOutline; 3] {
    [
        (
            "L",
            vec![
                [0.0, 0.0],
                [20.0, 0.0],
                [20.0, 6.0],
                [6.0, 6.0],
                [6.0, 14.0],
                [0.0, 14.0],
            ],
            vec![1, 4],
        ),
        (
            "T",
            vec![
                [0.0, 10.0],
                [6.0, 10.0],
                [6.0, 0.0],
                [12.0, 0.0],
                [12.0, 10.0],
                [18.0, 10.0],
                [18.0, 16.0],
                [0.0, 16.0],
            ],
            vec![2, 5, 7],
        ),
        (
            "U",
            vec![
                [0.0, 0.0],
                [20.0, 0.0],
                [20.0, 15.0],
                [14.0, 15.0],
                [14.0, 6.0],
                [6.0, 6.0],
                [6.0, 15.0],
                [0.0, 15.0],
            ],
            vec![2, 6],
        ),
    ]
}

/// The rise of a roof of one pitch over a rectilinear outline at `p`: its distance from the
/// outline's walls measured square to them (the L-infinity distance, which a straight skeleton
/// over right angles gives), walls listed in `skip` left out (gable ends).
fn rectilinear_rise(ring: &[[f64; 2]], skip: &[usize], p: [f64; 2]) -> f64 {
    (0..ring.len())
        .filter(|i| !skip.contains(i))
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
            let dx = (a[0].min(b[0]) - p[0]).max(p[0] - a[0].max(b[0])).max(0.0);
            let dy = (a[1].min(b[1]) - p[1]).max(p[1] - a[1].max(b[1])).max(0.0);
            dx.max(dy)
        })
        .fold(f64::INFINITY, f64::min)
}

#[tokio::test]
async fn hipped_and_gabled_roofs_on_l_t_and_u_outlines_follow_their_wings() {
    use citymesh_core::geo::LocalFrame;
    let (app, _db) = app().await;
    // Laid out in metres around (8.4 E, 49.01 N); hipped in the first row, gabled in the second.
    let frame = LocalFrame::new(8.4, 49.01, 0.0);
    let mut features = Vec::new();
    let mut drawn: Vec<(String, Vec<[f64; 2]>, Vec<usize>)> = Vec::new();
    for (k, (name, ring, ends)) in winged_outlines().into_iter().enumerate() {
        for (row, shape) in ["hipped", "gabled"].into_iter().enumerate() {
            let at = [k as f64 * 40.0, row as f64 * 30.0];
            let ring: Vec<[f64; 2]> = ring.iter().map(|p| [p[0] + at[0], p[1] + at[1]]).collect();
            let mut coordinates: Vec<[f64; 2]> = ring
                .iter()
                .map(|p| {
                    let (lon, lat, _) = frame.to_geographic([p[0], p[1], 0.0]);
                    [lon, lat]
                })
                .collect();
            coordinates.push(coordinates[0]);
            features.push(json!({"type": "Feature",
                "properties": {"height": 9, "roof:shape": shape},
                "geometry": {"type": "Polygon", "coordinates": [coordinates]}}));
            let skip = if shape == "gabled" {
                ends.clone()
            } else {
                Vec::new()
            };
            drawn.push((format!("{shape} {name}"), ring, skip));
        }
    }
    let a = post(&app, "application/geo+json", collection(features)).await;
    assert_eq!(
        a.status,
        StatusCode::OK,
        "{}",
        String::from_utf8_lossy(&a.body)
    );
    assert_valid_glb(&a.body);
    assert_eq!(a.header("x-citymesh-buildings"), "6");
    let (json, _) = common::decode::chunks(&a.body);
    let origin = &json["scenes"][0]["extras"]["origin"];
    let served = LocalFrame::new(
        origin["lon"].as_f64().unwrap(),
        origin["lat"].as_f64().unwrap(),
        0.0,
    );
    // No roof:height: the default pitch (30 degrees) over the roof's own run, half a wing's
    // width (3 m), under the cap of half the tagged height (4.5 m).
    let roof_height = 3.0 * 30f64.to_radians().tan();
    assert!(roof_height < 4.5);
    let triangles = common::decode::triangles(&a.body);
    for (i, (name, ring, skip)) in drawn.iter().enumerate() {
        let corners: Vec<[f64; 3]> = triangles
            .iter()
            .filter(|t| t.material == "roof" && t.feature == Some(i as u32))
            .flat_map(|t| t.corners)
            .collect();
        assert!(corners.len() >= 3, "{name}: no roof");
        let (mut top, mut eaves) = (f64::MIN, f64::MAX);
        for c in &corners {
            // Where the corner stands in the layout's metres.
            let (lon, lat, _) = served.to_geographic([c[0], -c[2], 0.0]);
            let p = frame.to_local(lon, lat, 0.0);
            let rise = rectilinear_rise(ring, skip, [p[0], p[1]]);
            let want = 9.0 - roof_height * (1.0 - rise / 3.0);
            assert!(
                (c[1] - want).abs() < 2e-3,
                "{name}: roof point ({:.3}, {:.3}) at {:.4} m, the skeleton gives {want:.4} m",
                p[0],
                p[1],
                c[1]
            );
            top = top.max(c[1]);
            eaves = eaves.min(c[1]);
        }
        assert!((top - 9.0).abs() < 1e-3, "{name}: top {top}");
        assert!(
            (top - eaves - roof_height).abs() < 2e-3,
            "{name}: roof {}",
            top - eaves
        );
        // A gabled roof's ridge runs to the middle of each wall that closes a wing.
        for &e in skip {
            let (a, b) = (ring[e], ring[(e + 1) % ring.len()]);
            let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
            let on_ridge = corners.iter().any(|c| {
                let (lon, lat, _) = served.to_geographic([c[0], -c[2], 0.0]);
                let p = frame.to_local(lon, lat, 0.0);
                (p[0] - mid[0]).abs() < 2e-3
                    && (p[1] - mid[1]).abs() < 2e-3
                    && (c[1] - 9.0).abs() < 2e-3
            });
            assert!(on_ridge, "{name}: no ridge end over the middle of wall {e}");
        }
    }
}

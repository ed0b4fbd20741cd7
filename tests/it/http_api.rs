//! The API as clients see it: `GET /scene` (the mission's name for the scene endpoint) against
//! `/scene.glb` and `/scene/stats`, content negotiation, and the OpenAPI document describing every
//! route with binary GLB bodies and JSON errors.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use common::{app_with, data_dir, dem_dir, get};
use http_body_util::BodyExt;
use serde_json::Value;
use tower::ServiceExt;

const BOX: &str = "bbox=8.39,49.04,8.41,49.06";

async fn kirchfeld_app(db: &tempfile::TempDir) -> axum::Router {
    let file = data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let file = file.display().to_string();
    app_with(&dem_dir(), &db.path().join("c.sqlite"), &["--osm", &file]).await
}

async fn get_accepting(
    app: &axum::Router,
    uri: &str,
    accept: &str,
) -> (StatusCode, String, Vec<u8>) {
    let response = app
        .clone()
        .oneshot(
            Request::get(uri)
                .header("accept", accept)
                .body(Body::empty())
                .unwrap(),
        )
        .await
        .unwrap();
    let status = response.status();
    let ctype = response.headers()["content-type"]
        .to_str()
        .unwrap()
        .to_owned();
    let body = response
        .into_body()
        .collect()
        .await
        .unwrap()
        .to_bytes()
        .to_vec();
    (status, ctype, body)
}

/// The statistics without the one figure that differs between two runs.
fn without_time(mut v: Value) -> Value {
    v.as_object_mut().unwrap().remove("generation_ms");
    v
}

#[tokio::test]
async fn scene_is_the_same_bytes_as_scene_glb_and_negotiates_json() {
    let db = tempfile::tempdir().unwrap();
    let app = kirchfeld_app(&db).await;
    let glb = get(&app, &format!("/scene.glb?{BOX}")).await;
    let scene = get(&app, &format!("/scene?{BOX}")).await;
    assert_eq!(scene.status, StatusCode::OK);
    assert_eq!(scene.header("content-type"), "model/gltf-binary");
    assert_eq!(scene.body, glb.body, "/scene and /scene.glb differ");
    assert_eq!(scene.header("etag"), glb.header("etag"));
    assert_eq!(
        scene.header("x-citymesh-buildings"),
        glb.header("x-citymesh-buildings")
    );
    let explicit = get(&app, &format!("/scene?{BOX}&format=glb")).await;
    assert_eq!(explicit.body, glb.body);

    // JSON: the statistics of /scene/stats, by parameter or by Accept.
    let stats = without_time(get(&app, &format!("/scene/stats?{BOX}")).await.json());
    let json = get(&app, &format!("/scene?{BOX}&format=json")).await;
    assert_eq!(json.header("content-type"), "application/json");
    assert_eq!(without_time(json.json()), stats);
    assert_eq!(stats["glb_bytes"], glb.body.len());
    let (status, ctype, body) =
        get_accepting(&app, &format!("/scene?{BOX}"), "application/json").await;
    assert_eq!(
        (status, ctype.as_str()),
        (StatusCode::OK, "application/json")
    );
    assert_eq!(without_time(serde_json::from_slice(&body).unwrap()), stats);
    // A client naming both gets the mesh; format wins over Accept.
    let (_, ctype, _) = get_accepting(
        &app,
        &format!("/scene?{BOX}"),
        "model/gltf-binary, application/json;q=0.5",
    )
    .await;
    assert_eq!(ctype, "model/gltf-binary");
    // Quality values decide, whatever the order (before, naming glTF at all gave the mesh).
    let (_, ctype, _) = get_accepting(
        &app,
        &format!("/scene?{BOX}"),
        "model/gltf-binary;q=0.5, application/json",
    )
    .await;
    assert_eq!(ctype, "application/json");
    let (_, ctype, _) = get_accepting(&app, &format!("/scene?{BOX}"), "*/*").await;
    assert_eq!(ctype, "model/gltf-binary");
    let (_, ctype, _) = get_accepting(
        &app,
        &format!("/scene?{BOX}&format=glb"),
        "application/json",
    )
    .await;
    assert_eq!(ctype, "model/gltf-binary");
    // Both variants say they vary with Accept, so caches keep them apart.
    assert_eq!(json.header("vary"), "accept");
    assert_eq!(scene.header("vary"), "accept");

    let bad = get(&app, &format!("/scene?{BOX}&format=xml")).await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
    assert_eq!(bad.json()["error"], "invalid_query");
    let missing = get(&app, "/scene").await;
    assert_eq!(missing.status, StatusCode::BAD_REQUEST);
    assert_eq!(missing.json()["error"], "missing_bbox");
}

#[tokio::test]
async fn openapi_describes_every_route_with_binary_glb_and_json_errors() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let doc = get(&app, "/openapi.json").await.json();
    let mut operations: Vec<String> = Vec::new();
    for (path, item) in doc["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            operations.push(format!(
                "{} {path} {}",
                method.to_uppercase(),
                op["operationId"].as_str().unwrap()
            ));
            // Every operation names its client errors, each a JSON error body.
            let responses = op["responses"].as_object().unwrap();
            assert!(
                responses.keys().any(|s| s.starts_with('4')),
                "{method} {path} lists no 4xx"
            );
            for (status, r) in responses {
                if status.starts_with('4') || status.starts_with('5') {
                    assert_eq!(
                        r["content"]["application/json"]["schema"]["$ref"],
                        "#/components/schemas/ErrorBody",
                        "{method} {path} {status}"
                    );
                }
            }
            // GLB bodies are binary strings, which generated clients download as bytes.
            if let Some(glb) = op["responses"]["200"]["content"].get("model/gltf-binary") {
                assert_eq!(glb["schema"]["type"], "string", "{method} {path}");
                assert_eq!(glb["schema"]["format"], "binary", "{method} {path}");
            }
        }
    }
    operations.sort();
    assert_eq!(
        operations,
        [
            "DELETE /classify/adapt/{id} delete_adapt",
            "DELETE /classify/{id} delete_batch",
            "GET / viewer",
            "GET /3dtiles-renderer tiles_renderer",
            "GET /3dtiles/area/{bbox}/content/{level}/{x}/{y}.glb content",
            "GET /3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}.subtree subtree",
            "GET /3dtiles/tileset.json tileset",
            "GET /3dtiles/world/{z}/{x}/{y} world_file",
            "GET /cesium cesium",
            "GET /classify/adapt/{id} get_adapt",
            "GET /classify/predictions predictions",
            "GET /classify/{id} get_batch",
            "GET /health health",
            "GET /metrics metrics",
            "GET /procedural.geojson procedural_geojson",
            "GET /procedural.glb procedural_glb",
            "GET /scene scene",
            "GET /scene.glb scene_glb",
            "GET /scene/stats scene_stats",
            "GET /tiles/{z}/{x}/{y}.glb tile_glb",
            "GET /viewer.js viewer_js",
            "POST /classify post_classify",
            "POST /classify/adapt post_adapt",
            "POST /scene.glb post_scene",
        ]
    );
    assert_eq!(doc["servers"][0]["url"], "/");
    // Each documented path answers (not the fallback's 404 `not_found`) when called as written.
    for uri in [
        "/tiles/16/34297/22502.glb",
        "/3dtiles/area/8.4,49.01,8.41,49.02/subtrees/0/0/0.subtree",
        "/scene?bbox=8.400,49.010,8.409,49.017",
    ] {
        let a = get(&app, uri).await;
        assert_eq!(a.status, StatusCode::OK, "{uri}");
    }
}

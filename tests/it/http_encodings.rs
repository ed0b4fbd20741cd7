//! The three GLB encodings over HTTP on real Karlsruhe-Kirchfeld data: each passes the Khronos
//! validator (meshopt also once decoded), meshopt decodes to exactly the quantized triangles,
//! quantized triangles sit on the plain ones within half a quantization step, and `?encoding=`,
//! the `Accept` hint and the cache keys agree.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use common::decode::{Triangle, chunks, decode_meshopt, feature_rows, triangles};
use common::{get, validate_glb};
use http_body_util::BodyExt;
use serde_json::Value;
use std::collections::HashMap;
use tower::ServiceExt;

async fn app(db: &tempfile::TempDir) -> axum::Router {
    common::kirchfeld_app(db).await
}

/// No error, warning or note, except the two the feature metadata brings: the validator cannot
/// look inside `EXT_mesh_features` and `EXT_structural_metadata`, and so takes the property
/// tables' buffer views for unused. Those are checked by [`feature_rows`] instead.
fn assert_spotless(glb: &[u8], what: &str) {
    let r = validate_glb(glb);
    assert_eq!(
        (&r["errors"], &r["warnings"]),
        (&0.into(), &0.into()),
        "{what}: {r}"
    );
    let (json, _) = chunks(glb);
    let table_views: Vec<String> = json["extensions"]["EXT_structural_metadata"]["propertyTables"]
        [0]["properties"]
        .as_object()
        .into_iter()
        .flat_map(|p| p.values())
        .flat_map(|p| [&p["values"], &p["stringOffsets"]])
        .filter_map(Value::as_u64)
        .map(|k| format!("UNUSED_OBJECT /bufferViews/{k}:"))
        .collect();
    let other: Vec<&Value> = r["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| {
            let m = m.as_str().unwrap();
            !(m.starts_with("UNSUPPORTED_EXTENSION")
                && (m.contains("'EXT_mesh_features'") || m.contains("'EXT_structural_metadata'")))
                && !table_views.iter().any(|v| m.starts_with(v.as_str()))
        })
        .collect();
    assert!(other.is_empty(), "{what}: {other:?}");
    assert!(
        r["messages"].as_array().unwrap().len() < 200,
        "{what}: messages cut short"
    );
    assert!(!feature_rows(glb).is_empty(), "{what}: no feature rows");
}

/// A triangle turned to start at its smallest corner, for comparing sets of triangles (with its
/// colour and feature).
fn canonical(t: &Triangle) -> ([[i64; 3]; 3], [u8; 4], Option<u32>) {
    let key = t.raw.map(|p| p.map(|c| (c * 1000.0).round() as i64));
    let m = (0..3).min_by_key(|&k| key[k]).unwrap();
    (
        [key[m], key[(m + 1) % 3], key[(m + 2) % 3]],
        t.colour,
        t.feature,
    )
}

/// Checks one GLB served in the three encodings; returns their sizes.
fn check_encodings(plain: &[u8], quantized: &[u8], meshopt: &[u8], normals: bool) -> [usize; 3] {
    assert_spotless(plain, "plain");
    assert_spotless(quantized, "quantized");
    // As sent, the validator only notes that it cannot look inside meshopt views.
    let raw = validate_glb(meshopt);
    assert_eq!(
        (&raw["errors"], &raw["warnings"]),
        (&0.into(), &0.into()),
        "meshopt: {raw}"
    );
    assert_spotless(&decode_meshopt(meshopt), "meshopt, decoded");
    // The same rows in every encoding.
    let rows = feature_rows(plain);
    assert_eq!(feature_rows(quantized), rows);
    assert_eq!(feature_rows(meshopt), rows);

    // Meshopt is the quantized data, reordered: exactly the same triangles.
    let (tq, tm) = (triangles(quantized), triangles(meshopt));
    let mut a: Vec<_> = tq.iter().map(canonical).collect();
    let mut b: Vec<_> = tm.iter().map(canonical).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b, "meshopt decodes to the quantized triangles");

    // Quantized corners are plain corners moved by at most half a step per axis.
    let (json, _) = chunks(quantized);
    let m = json["nodes"][0]["matrix"].as_array().unwrap();
    // The step is the length of the matrix's first column.
    let step = (0..3)
        .map(|r| m[r].as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt();
    let tp = triangles(plain);
    let cell = 0.05;
    let mut grid: HashMap<[i64; 3], Vec<[f64; 3]>> = HashMap::new();
    for t in &tp {
        for p in t.corners {
            grid.entry(p.map(|c| (c / cell).floor() as i64))
                .or_default()
                .push(p);
        }
    }
    let slack = step / 2.0 * 3f64.sqrt() + 1e-3;
    for t in &tq {
        for p in t.corners {
            let c = p.map(|v| (v / cell).floor() as i64);
            let near = (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dz| {
                        grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz])
                            .is_some_and(|ps| {
                                ps.iter().any(|q| {
                                    (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt()
                                        <= slack
                                })
                            })
                    })
                })
            });
            assert!(
                near,
                "a quantized corner {p:?} is not within {slack} m of a plain one"
            );
        }
    }
    // Only triangles that quantization collapsed are left out.
    assert!(
        tq.len() <= tp.len() && tq.len() * 100 >= tp.len() * 98,
        "{} vs {}",
        tq.len(),
        tp.len()
    );

    // Normals: stored for Earth-centred content (CesiumJS), left to the client otherwise.
    for glb in [plain, quantized, meshopt] {
        let (json, _) = chunks(glb);
        let has = json["meshes"][0]["primitives"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p["attributes"].get("NORMAL").is_some());
        assert_eq!(has, normals);
    }
    [plain.len(), quantized.len(), meshopt.len()]
}

#[tokio::test]
async fn xyz_tiles_in_every_encoding_draw_the_same_buildings() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let tile = |e: &str| format!("/tiles/16/34297/22491.glb?encoding={e}");
    let plain = get(&app, &tile("plain")).await;
    let quantized = get(&app, &tile("quantized")).await;
    let meshopt = get(&app, &tile("meshopt")).await;
    for a in [&plain, &quantized, &meshopt] {
        assert_eq!(a.status, StatusCode::OK);
    }
    // Plain is the default: the same bytes without the parameter.
    assert_eq!(
        get(&app, "/tiles/16/34297/22491.glb").await.body,
        plain.body
    );
    let [p, q, m] = check_encodings(&plain.body, &quantized.body, &meshopt.body, false);
    assert!(m * 2 < q && q < p, "sizes {p} {q} {m}");
}

#[tokio::test]
async fn content_tiles_in_every_encoding_draw_the_same_buildings() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let region = "8.392,49.046,8.401,49.053";
    let tileset = get(
        &app,
        &format!("/3dtiles/tileset.json?bbox={region}&tiling=implicit"),
    )
    .await
    .json();
    let leaf = tileset["root"]["implicitTiling"]["availableLevels"]
        .as_u64()
        .unwrap()
        - 1;
    let n = 1u32 << leaf;
    let mut found = None;
    'search: for x in 0..n {
        for y in 0..n {
            let uri = format!("/3dtiles/area/{region}/content/{leaf}/{x}/{y}.glb");
            if get(&app, &uri).await.status == StatusCode::OK {
                found = Some(uri);
                break 'search;
            }
        }
    }
    let uri = found.expect("a content tile in the region");
    let plain = get(&app, &format!("{uri}?encoding=plain")).await;
    let quantized = get(&app, &format!("{uri}?encoding=quantized")).await;
    let default = get(&app, &uri).await;
    // Content is meshopt by default.
    assert_eq!(
        get(&app, &format!("{uri}?encoding=meshopt")).await.body,
        default.body
    );
    let [p, q, m] = check_encodings(&plain.body, &quantized.body, &default.body, true);
    assert!(m * 2 < q && q < p, "sizes {p} {q} {m}");

    // A tileset asked for another encoding passes it to its content URIs.
    let other = get(
        &app,
        &format!("/3dtiles/tileset.json?bbox={region}&encoding=plain"),
    )
    .await
    .json();
    assert!(
        other["root"]["content"]["uri"]
            .as_str()
            .unwrap()
            .ends_with(".glb?encoding=plain")
    );
    assert!(
        tileset["root"]["content"]["uri"]
            .as_str()
            .unwrap()
            .ends_with(".glb")
    );
}

#[tokio::test]
async fn the_accept_hint_chooses_the_encoding_and_each_encoding_is_cached_apart() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let uri = "/tiles/16/34297/22491.glb";
    let ask = |accept: &'static str| {
        let app = app.clone();
        async move {
            let r = app
                .oneshot(
                    Request::get(uri)
                        .header("accept", accept)
                        .body(Body::empty())
                        .unwrap(),
                )
                .await
                .unwrap();
            let headers = r.headers().clone();
            (
                headers,
                r.into_body().collect().await.unwrap().to_bytes().to_vec(),
            )
        }
    };
    let (h1, hinted) = ask("model/gltf-binary; encoding=quantized, */*;q=0.1").await;
    assert_eq!(h1["x-citymesh-cache"], "miss");
    assert!(
        h1["vary"]
            .to_str()
            .unwrap()
            .to_ascii_lowercase()
            .contains("accept")
    );
    let asked = get(&app, &format!("{uri}?encoding=quantized")).await;
    assert_eq!(asked.body, hinted);
    assert_eq!(asked.header("x-citymesh-cache"), "hit");
    // The parameter wins over the hint; an unknown hint is ignored.
    let (_, plain) = ask("model/gltf-binary; encoding=draco").await;
    let (h2, plain_again) = ask("model/gltf-binary").await;
    assert_eq!(plain, plain_again);
    assert_eq!(h2["x-citymesh-cache"], "hit");
    assert_ne!(plain, hinted);
    let p = get(&app, &format!("{uri}?encoding=plain")).await;
    assert_ne!(p.header("etag"), asked.header("etag"));

    // An unknown encoding in the query is the client's mistake, said in JSON.
    let bad = get(&app, &format!("{uri}?encoding=draco")).await;
    assert_eq!(bad.status, StatusCode::BAD_REQUEST);
    let body = bad.json();
    assert_eq!(body["error"], "invalid_query");
    assert!(
        body["detail"].as_str().unwrap().contains("meshopt"),
        "{body}"
    );
}

#[tokio::test]
async fn box_scenes_and_their_figures_come_from_the_scene_cache() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let bbox = "8.392,49.046,8.401,49.053";
    let first = get(&app, &format!("/scene.glb?bbox={bbox}")).await;
    assert_eq!(first.status, StatusCode::OK);
    assert_eq!(first.header("x-citymesh-cache"), "miss");
    let again = get(&app, &format!("/scene?bbox={bbox}")).await;
    assert_eq!(again.header("x-citymesh-cache"), "hit");
    assert_eq!(again.body, first.body);
    assert_eq!(again.header("etag"), first.header("etag"));
    // The figures are those of the one generation.
    let stats = get(&app, &format!("/scene/stats?bbox={bbox}")).await.json();
    let ms: f64 = first.header("x-citymesh-generation-ms").parse().unwrap();
    assert!(
        (stats["generation_ms"].as_f64().unwrap() - ms).abs() < 1e-3,
        "{stats}"
    );
    // Another encoding is another entry.
    let quantized = get(&app, &format!("/scene.glb?bbox={bbox}&encoding=quantized")).await;
    assert_eq!(quantized.header("x-citymesh-cache"), "miss");
    assert_ne!(quantized.body, first.body);
}

//! Buildings on steep ground (Andorra, `N42E001.hgt`): `height` counts from the lowest ground
//! along the outline, as Simple 3D Buildings defines it; with `height_base=highest` (or the
//! server's `--height-base highest`) from the highest, as the paper's Figure 5 does.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh_core::terrain::{ElevationModel, HgtTile};
use common::{app_with, assert_valid_glb, dem_dir, post_json};
use serde_json::{Value, json};
use std::sync::Arc;

/// A 20 m x 14 m footprint on a slope above Andorra la Vella.
fn ring() -> Vec<(f64, f64)> {
    let (lon, lat) = (1.5245, 42.5045);
    let (dlon, dlat) = (10.0 / 82_000.0, 7.0 / 111_100.0);
    vec![
        (lon - dlon, lat - dlat),
        (lon + dlon, lat - dlat),
        (lon + dlon, lat + dlat),
        (lon - dlon, lat + dlat),
    ]
}

fn collection(height: f64) -> Value {
    let mut coords: Vec<[f64; 2]> = ring().iter().map(|p| [p.0, p.1]).collect();
    coords.push(coords[0]);
    json!({"type": "FeatureCollection", "features": [{
        "type": "Feature",
        "properties": {"building": "yes", "height": height, "roof:shape": "flat"},
        "geometry": {"type": "Polygon", "coordinates": [coords]},
    }]})
}

fn andorra_model() -> ElevationModel {
    let bytes = std::fs::read(dem_dir().join("N42E001.hgt")).unwrap();
    ElevationModel::new(vec![Arc::new(HgtTile::from_bytes(42, 1, &bytes).unwrap())])
}

/// The highest point of the building (every triangle but the ground's), metres above the
/// frame's origin (0 m, the DEM's reference).
fn top_of(glb: &[u8]) -> f64 {
    common::decode::triangles(glb)
        .iter()
        .filter(|t| t.material != "ground")
        .flat_map(|t| t.corners.map(|c| c[1]))
        .fold(f64::MIN, f64::max)
}

#[tokio::test]
async fn height_counts_from_the_lowest_ground_of_the_outline_or_as_asked_from_the_highest() {
    let (lowest, highest) = andorra_model().height_range_along(&ring());
    // The slope is real: the outline's ground rises by metres, well under the building.
    assert!(
        highest - lowest > 3.0 && highest - lowest < 25.0,
        "{lowest}..{highest}"
    );

    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let default = post_json(&app, "/scene.glb", collection(30.0)).await;
    assert_eq!(
        default.status,
        StatusCode::OK,
        "{}",
        String::from_utf8_lossy(&default.body)
    );
    assert_eq!(default.header("x-citymesh-ground"), "dem");
    assert_valid_glb(&default.body);
    let top = top_of(&default.body);
    assert!(
        (top - (lowest + 30.0)).abs() <= 0.05,
        "top {top}, lowest ground {lowest}"
    );

    let paper = post_json(&app, "/scene.glb?height_base=highest", collection(30.0)).await;
    assert_eq!(paper.status, StatusCode::OK);
    let top = top_of(&paper.body);
    assert!(
        (top - (highest + 30.0)).abs() <= 0.05,
        "top {top}, highest ground {highest}"
    );

    // The server's flag sets the default; the parameter still overrides it.
    let db2 = tempfile::tempdir().unwrap();
    let paper_server = app_with(
        &dem_dir(),
        &db2.path().join("c.sqlite"),
        &["--height-base", "highest"],
    )
    .await;
    let by_flag = post_json(&paper_server, "/scene.glb", collection(30.0)).await;
    assert_eq!(by_flag.body, paper.body);
    let asked = post_json(
        &paper_server,
        "/scene.glb?height_base=lowest",
        collection(30.0),
    )
    .await;
    assert_eq!(asked.body, default.body);

    // A shed lower than the slope rises: its top stays 1 m above the uphill ground.
    let shed = post_json(&app, "/scene.glb", collection(2.0)).await;
    let top = top_of(&shed.body);
    assert!(
        (top - (highest + 1.0)).abs() <= 0.05,
        "top {top}, highest ground {highest}"
    );

    // A wrong value says what it takes.
    let wrong = post_json(&app, "/scene.glb?height_base=middle", collection(30.0)).await;
    assert_eq!(wrong.status, StatusCode::BAD_REQUEST);
    assert!(wrong.text().contains("lowest"), "{}", wrong.text());
}

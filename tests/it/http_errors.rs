//! Every bad request gets a 4xx with a JSON body that says what to fix; never a 500 or a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use common::{app_with, dem_dir, get};
use rstest::rstest;

#[rstest]
#[case("/scene.glb", 400, "missing_bbox", "?bbox=minLon,minLat,maxLon,maxLat")]
#[case(
    "/scene.glb?bbox=",
    400,
    "invalid_bbox",
    "expected four comma-separated numbers"
)]
#[case("/scene.glb?bbox=abc", 400, "invalid_bbox", "got 1 values")]
#[case("/scene.glb?bbox=8.39,49.04,8.41", 400, "invalid_bbox", "got 3 values")]
#[case(
    "/scene.glb?bbox=8.39,49.04,8.41,49.06,1",
    400,
    "invalid_bbox",
    "got 5 values"
)]
#[case(
    "/scene.glb?bbox=8.39,49.04,eight,49.06",
    400,
    "invalid_bbox",
    "value 2 ('eight') is not a number"
)]
#[case(
    "/scene.glb?bbox=NaN,49.04,8.41,49.06",
    400,
    "invalid_bbox",
    "value 0 is NaN, which is not a finite number"
)]
#[case(
    "/scene.glb?bbox=8.39,49.04,8.41,inf",
    400,
    "invalid_bbox",
    "value 3 is inf"
)]
#[case(
    "/scene.glb?bbox=8.41,49.04,8.39,49.06",
    400,
    "invalid_bbox",
    "minLon 8.41 must be smaller than maxLon 8.39"
)]
#[case(
    "/scene.glb?bbox=8.39,49.06,8.41,49.04",
    400,
    "invalid_bbox",
    "minLat 49.06 must be smaller than maxLat 49.04"
)]
#[case(
    "/scene.glb?bbox=8.39,49.04,8.39,49.06",
    400,
    "invalid_bbox",
    "minLon 8.39 must be smaller"
)]
#[case(
    "/scene.glb?bbox=8.39,85.06,8.41,85.07",
    400,
    "invalid_bbox",
    "latitude 85.06 is outside -85.0511..85.0511"
)]
#[case(
    "/scene.glb?bbox=8.39,-86,8.41,49",
    400,
    "invalid_bbox",
    "latitude -86 is outside"
)]
#[case(
    "/scene.glb?bbox=-190,49.04,8.41,49.06",
    400,
    "invalid_bbox",
    "longitude -190 is outside -180..180"
)]
#[case(
    "/scene.glb?bbox=8,49,9,50",
    400,
    "bbox_too_large",
    "the bbox covers 8"
)]
#[case(
    "/scene.glb?bbox=8.39,49.04,8.41,49.06&bbox=1,2,3,4",
    400,
    "invalid_query",
    "duplicate field"
)]
#[case(
    "/tiles/16/abc/22492.glb",
    400,
    "invalid_tile",
    "x 'abc' is not a whole number"
)]
#[case(
    "/tiles/16/34297/1e3.glb",
    400,
    "invalid_tile",
    "y '1e3' is not a whole number"
)]
#[case(
    "/tiles/-1/0/0.glb",
    400,
    "invalid_tile",
    "z '-1' is not a whole number"
)]
#[case("/tiles/31/0/0.glb", 400, "invalid_tile", "zoom 31 is outside 0..=30")]
#[case(
    "/tiles/16/65536/0.glb",
    400,
    "invalid_tile",
    "x 65536 is outside 0..65536 for zoom 16"
)]
#[case(
    "/tiles/16/0/65536.glb",
    400,
    "invalid_tile",
    "y 65536 is outside 0..65536 for zoom 16"
)]
#[case(
    "/tiles/16/0/99999999999.glb",
    400,
    "invalid_tile",
    "y '99999999999' is not a whole number"
)]
#[case(
    "/tiles/16/34297/22492.png",
    404,
    "unknown_format",
    "tiles are served as .glb"
)]
#[case(
    "/tiles/16/34297/22492",
    404,
    "unknown_format",
    "tiles are served as .glb"
)]
#[case(
    "/tiles/5/16/10.glb",
    404,
    "zoom_not_served",
    "this server serves zoom 12 to 20"
)]
#[case("/tiles/21/0/0.glb", 404, "zoom_not_served", "zoom 21 is not served")]
#[case(
    "/tiles/16/34297",
    404,
    "not_found",
    "nothing is served at /tiles/16/34297"
)]
#[case("/no/such/thing", 404, "not_found", "see /docs")]
#[tokio::test]
async fn bad_requests_get_a_json_error(
    #[case] uri: &str,
    #[case] status: u16,
    #[case] code: &str,
    #[case] detail: &str,
) {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(&dem_dir(), &db.path().join("c.sqlite"), &[]).await;
    let answer = get(&app, uri).await;
    assert_eq!(
        answer.status,
        StatusCode::from_u16(status).unwrap(),
        "{uri}: {}",
        String::from_utf8_lossy(&answer.body)
    );
    assert_eq!(answer.header("content-type"), "application/json");
    let body = answer.json();
    assert_eq!(body["error"], code, "{uri}: {body}");
    let text = body["detail"].as_str().unwrap();
    assert!(
        text.contains(detail),
        "{uri}: detail '{text}' lacks '{detail}'"
    );
}

#[tokio::test]
async fn the_area_limit_is_configurable() {
    let db = tempfile::tempdir().unwrap();
    let app = app_with(
        &dem_dir(),
        &db.path().join("c.sqlite"),
        &["--max-bbox-km2", "1"],
    )
    .await;
    let answer = get(&app, "/scene.glb?bbox=8.39,49.04,8.41,49.06").await;
    assert_eq!(answer.status, StatusCode::BAD_REQUEST);
    assert_eq!(
        answer.json()["detail"],
        "the bbox covers 3.25 km², more than this server's limit of 1 km²: request a smaller area or tiles"
    );
}

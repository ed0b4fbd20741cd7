//! The pages people open: the three.js viewer at `/`, CesiumJS at `/cesium`, and
//! 3d-tiles-renderer at `/3dtiles-renderer`. Their JavaScript libraries come from npm
//! (`npm ci` installs them) and are served by citymesh under `/vendor/`, so they work with no
//! internet; the viewer falls back to a CDN when they are not installed.

use crate::error::ErrorBody;
use crate::state::AppState;
use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{Html, IntoResponse, Response};
use citymesh_core::procedural::{DEFAULT_LAT, DEFAULT_LON};

use std::sync::LazyLock;

const VIEWER_JS: &str = include_str!("pages/viewer.js");
/// What every page shows when its libraries do not load, shared by the three pages.
const ASSETS_MISSING_JS: &str = include_str!("pages/assets-missing.js");

/// The panel of a picked building's properties, shared by the two 3D Tiles pages.
const PICKED_PANEL_JS: &str = include_str!("pages/picked-panel.js");

/// A page with the shared scripts put in their places.
fn page(html: &str) -> String {
    html.replace("__ASSETS_MISSING__", ASSETS_MISSING_JS)
        .replace("__PICKED_PANEL__", PICKED_PANEL_JS)
}

static VIEWER_HTML: LazyLock<String> = LazyLock::new(|| page(include_str!("pages/viewer.html")));
static CESIUM_HTML: LazyLock<String> = LazyLock::new(|| page(include_str!("pages/cesium.html")));
static TILES_RENDERER_HTML: LazyLock<String> =
    LazyLock::new(|| page(include_str!("pages/tiles3d-renderer.html")));

/// The three.js viewer.
///
/// `?lon=&lat=&zoom=&radius=` choose the place (default: the served buildings' centre, or the
/// demo city).
#[utoipa::path(get, path = "/", tag = "pages",
    responses(
        (status = 200, description = "The viewer page", content_type = "text/html", body = String),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn viewer(State(state): State<AppState>) -> Html<String> {
    let (lon, lat) = state
        .generator
        .source
        .extent()
        .map_or((DEFAULT_LON, DEFAULT_LAT), |b| b.center());
    // three.js from this server when npm installed it, else from a CDN.
    let three = if state
        .assets_dir
        .join("three/build/three.module.js")
        .is_file()
    {
        "/vendor/three/"
    } else {
        "https://cdn.jsdelivr.net/npm/three@0.187.0/"
    };
    let defaults = serde_json::json!({"lon": lon, "lat": lat, "zoom": 16, "three": three});
    Html(VIEWER_HTML.replace("__DEFAULTS__", &defaults.to_string()))
}

/// The viewer's script.
#[utoipa::path(get, path = "/viewer.js", tag = "pages",
    responses(
        (status = 200, description = "The script", content_type = "text/javascript", body = String),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn viewer_js() -> Response {
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/javascript; charset=utf-8"),
        )],
        VIEWER_JS,
    )
        .into_response()
}

/// The CesiumJS page: this server's 3D Tiles on an offline globe.
#[utoipa::path(get, path = "/cesium", tag = "pages",
    responses(
        (status = 200, description = "The page", content_type = "text/html", body = String),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn cesium(State(state): State<AppState>) -> Html<String> {
    Html(with_imagery_credit(&CESIUM_HTML, &state))
}

/// The 3d-tiles-renderer page: this server's 3D Tiles in three.js.
#[utoipa::path(get, path = "/3dtiles-renderer", tag = "pages",
    responses(
        (status = 200, description = "The page", content_type = "text/html", body = String),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn tiles_renderer(State(state): State<AppState>) -> Html<String> {
    Html(with_imagery_credit(&TILES_RENDERER_HTML, &state))
}

/// A 3D Tiles page with the classifier's imagery attribution (`--imagery-attribution`), shown
/// when the page asks for `roofs=classified`, as a JavaScript string (`<` escaped, so no text
/// can close the script).
fn with_imagery_credit(html: &str, state: &AppState) -> String {
    let text = if state.classifier.is_some() {
        state.generator.roofs.imagery_attribution.as_str()
    } else {
        ""
    };
    let js = serde_json::to_string(text)
        .unwrap_or_else(|_| "\"\"".to_owned())
        .replace('<', "\\u003c");
    html.replace("__IMAGERY_CREDIT__", &js)
}

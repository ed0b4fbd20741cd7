//! The HTTP surface: one file per resource, all thin. Handlers check their input, ask the
//! generator or a cache, and shape the response; they never compute geometry themselves.

mod conditional;
mod health;
mod metrics;
mod pages;
mod procedural;
mod scene;
mod scene_stats;
mod scene_upload;
mod tiles;
mod tiles3d;

use crate::error::{AppError, ErrorBody};
use crate::state::AppState;
use axum::Router;
use axum::http::Method;
use axum::routing::get;
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{NotForContentType, Predicate, SizeAbove};
use tower_http::cors::{Any, CorsLayer};
use tower_http::services::ServeDir;
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa_swagger_ui::SwaggerUi;

/// The OpenAPI description of every route.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "citymesh",
        description = "3D city meshes (glTF binary) from OpenStreetMap buildings and SRTM terrain, generated on demand."
    ),
    paths(
        health::health,
        scene::scene_glb,
        scene_stats::scene_stats,
        tiles::tile_glb
    ),
    components(schemas(ErrorBody, health::Health))
)]
pub struct ApiDoc;

/// The OpenAPI document as pretty JSON, exactly as served at `/openapi.json`.
pub fn openapi_json() -> String {
    ApiDoc::openapi()
        .to_pretty_json()
        .expect("the OpenAPI document always serialises")
}

/// The whole application, ready to serve or to call in tests with `oneshot`.
pub fn app(state: AppState) -> Router {
    let assets = state.assets_dir.clone();
    // Browsers on other origins (CesiumJS and three.js apps) may fetch everything and read the
    // figures and validators.
    let cors = CorsLayer::new()
        .allow_origin(Any)
        .allow_methods([Method::GET, Method::HEAD, Method::OPTIONS])
        .allow_headers(Any)
        .expose_headers(Any);
    // JSON and text compress well; GLB is binary floats and goes out as it is (compressing it on
    // every cached request would cost more CPU than it saves).
    let compression = CompressionLayer::new().compress_when(
        SizeAbove::new(256)
            .and(NotForContentType::const_new("model/gltf-binary"))
            .and(NotForContentType::IMAGES),
    );
    Router::new()
        .route("/", get(pages::viewer))
        .route("/viewer.js", get(pages::viewer_js))
        .route("/cesium", get(pages::cesium))
        .route("/3dtiles-renderer", get(pages::tiles_renderer))
        .nest_service("/vendor/three", ServeDir::new(assets.join("three")))
        .nest_service(
            "/vendor/3d-tiles-renderer",
            ServeDir::new(assets.join("3d-tiles-renderer")),
        )
        .nest_service(
            "/vendor/cesium",
            ServeDir::new(assets.join("cesium/Build/Cesium")),
        )
        .route("/health", get(health::health))
        .route("/metrics", get(metrics::metrics))
        .route(
            "/scene.glb",
            get(scene::scene_glb).post(scene_upload::post_scene),
        )
        .route("/procedural.geojson", get(procedural::procedural_geojson))
        .route("/procedural.glb", get(procedural::procedural_glb))
        .route("/scene/stats", get(scene_stats::scene_stats))
        .route("/tiles/{z}/{x}/{y}", get(tiles::tile_glb))
        .route("/3dtiles/tileset.json", get(tiles3d::tileset))
        .route(
            "/3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}",
            get(tiles3d::subtree),
        )
        .route(
            "/3dtiles/area/{bbox}/content/{level}/{x}/{y}",
            get(tiles3d::content),
        )
        .merge(SwaggerUi::new("/docs").url("/openapi.json", ApiDoc::openapi()))
        .fallback(not_found)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            metrics::track,
        ))
        .layer(compression)
        .layer(cors)
        .layer(TraceLayer::new_for_http())
        .with_state(state)
}

async fn not_found(uri: axum::http::Uri) -> AppError {
    AppError::not_found(
        "not_found",
        format!("nothing is served at {}; see /docs for the API", uri.path()),
    )
}

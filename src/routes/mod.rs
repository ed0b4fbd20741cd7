//! The HTTP surface: one file per resource, all thin. Handlers parse their input, ask the cache
//! or the pipeline, and shape the response; they never compute geometry themselves. Every route
//! is registered through utoipa-axum's `OpenApiRouter` with `routes!`, so a route cannot exist
//! without its OpenAPI description.

mod accept;
mod classify;
mod classify_adapt;
mod conditional;
mod cross_origin;
mod error_bodies;

pub use error_bodies::{MAX_HEADER_BYTES, MAX_HEADER_COUNT, MAX_URI_BYTES};
mod headers;
mod health;
mod metrics;
mod pages;
mod params;
mod procedural;
mod request_body;
mod roofs;
mod scene;
pub mod scene_stats;
mod scene_upload;
mod schemas;
mod tiles;
mod tiles3d;
mod vendor;
mod world;

use crate::error::{AppError, ErrorBody};
use crate::state::AppState;
use axum::Router;
use axum::http::Method;
use tower_http::compression::CompressionLayer;
use tower_http::compression::predicate::{NotForContentType, Predicate, SizeAbove};
use tower_http::cors::{Any, CorsLayer};
use tower_http::services::ServeDir;
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa::openapi::OpenApi as OpenApiDocument;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;
use utoipa_swagger_ui::SwaggerUi;

/// The document's frame: what the API is, its tags and servers. The paths come from the routes.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "citymesh",
        description = "3D city meshes (glTF binary and 3D Tiles) from OpenStreetMap buildings and SRTM terrain, generated on demand.",
        license(name = "MIT OR Apache-2.0", identifier = "MIT OR Apache-2.0")
    ),
    servers((url = "/", description = "This server")),
    // No operation needs credentials.
    security(()),
    tags(
        (name = "meshes", description = "Scenes and XYZ tiles as binary glTF"),
        (name = "3d tiles", description = "3D Tiles 1.1 with implicit quadtree tiling, for CesiumJS and 3d-tiles-renderer"),
        (name = "procedural", description = "Seeded procedural cities through the same generator"),
        (name = "classification", description = "Roof shapes classified from imagery: queued jobs and their predictions"),
        (name = "service", description = "Health and metrics"),
        (name = "pages", description = "Viewers for people"),
    ),
    components(schemas(ErrorBody))
)]
struct ApiDoc;

/// Routes whose last segment carries a fixed suffix after a parameter. axum's router cannot
/// match a suffix, so the handler takes the whole segment and checks the suffix; the document
/// names the path as clients call it.
const SUFFIXED_PATHS: [(&str, &str); 3] = [
    ("/tiles/{z}/{x}/{y}", "/tiles/{z}/{x}/{y}.glb"),
    (
        "/3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}",
        "/3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}.subtree",
    ),
    (
        "/3dtiles/area/{bbox}/content/{level}/{x}/{y}",
        "/3dtiles/area/{bbox}/content/{level}/{x}/{y}.glb",
    ),
];

/// Every route with its description.
fn api_router() -> OpenApiRouter<AppState> {
    OpenApiRouter::with_openapi(ApiDoc::openapi())
        .routes(routes!(pages::viewer))
        .routes(routes!(pages::viewer_js))
        .routes(routes!(pages::cesium))
        .routes(routes!(pages::tiles_renderer))
        .routes(routes!(health::health))
        .routes(routes!(metrics::metrics))
        .routes(routes!(scene::scene))
        .routes(routes!(scene::scene_glb, scene_upload::post_scene))
        .routes(routes!(scene_stats::scene_stats))
        .routes(routes!(tiles::tile_glb))
        .routes(routes!(procedural::procedural_geojson))
        .routes(routes!(procedural::procedural_glb))
        .routes(routes!(tiles3d::tileset))
        .routes(routes!(tiles3d::subtree))
        .routes(routes!(tiles3d::content))
        .routes(routes!(world::world_file))
        .routes(routes!(classify::post_classify))
        .routes(routes!(classify::predictions))
        .routes(routes!(classify::get_batch, classify::delete_batch))
        .routes(routes!(classify_adapt::post_adapt))
        .routes(routes!(
            classify_adapt::get_adapt,
            classify_adapt::delete_adapt
        ))
}

/// Renames the suffixed paths to the form clients call.
fn with_suffixes(mut doc: OpenApiDocument) -> OpenApiDocument {
    for (route, documented) in SUFFIXED_PATHS {
        if let Some(item) = doc.paths.paths.remove(route) {
            doc.paths.paths.insert(documented.to_owned(), item);
        }
    }
    doc
}

/// The OpenAPI document, exactly as served at `/openapi.json`.
pub fn openapi() -> OpenApiDocument {
    with_suffixes(api_router().split_for_parts().1)
}

/// The OpenAPI document as pretty JSON, exactly as served at `/openapi.json`.
pub fn openapi_json() -> String {
    openapi()
        .to_pretty_json()
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

/// The whole application, ready to serve or to call in tests with `oneshot`.
pub fn app(state: AppState) -> Router {
    let assets = state.assets_dir.clone();
    // Browsers on other origins (CesiumJS and three.js apps) may fetch everything and read the
    // figures and validators; changing state is for the origins `cross_origin::guard` allows.
    let cors = CorsLayer::new()
        .allow_origin(Any)
        .allow_methods([
            Method::GET,
            Method::HEAD,
            Method::OPTIONS,
            Method::POST,
            Method::DELETE,
        ])
        .allow_headers(Any)
        .expose_headers(Any);
    // JSON and text compress well; GLB is binary floats and goes out as it is (compressing it on
    // every cached request would cost more CPU than it saves).
    let compression = CompressionLayer::new().compress_when(
        SizeAbove::new(256)
            .and(NotForContentType::const_new(headers::GLB))
            .and(NotForContentType::IMAGES),
    );
    let (router, doc) = api_router().split_for_parts();
    // Each package's files, never what a link inside it points to elsewhere.
    let package = |dir: std::path::PathBuf| {
        let guard = axum::middleware::from_fn_with_state(
            std::sync::Arc::new(dir.clone()),
            vendor::contained,
        );
        tower::Layer::layer(&guard, ServeDir::new(dir))
    };
    router
        .nest_service("/vendor/three", package(assets.join("three")))
        .nest_service(
            "/vendor/3d-tiles-renderer",
            package(assets.join("3d-tiles-renderer")),
        )
        .nest_service(
            "/vendor/cesium",
            package(assets.join("cesium/Build/Cesium")),
        )
        .merge(SwaggerUi::new("/docs").url("/openapi.json", with_suffixes(doc)))
        .fallback(not_found)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            request_body::guard,
        ))
        .layer(axum::middleware::from_fn(error_bodies::json_errors))
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            metrics::track,
        ))
        .layer(compression)
        .layer(cors)
        // Outside the CORS layer, so a refused preflight is refused too.
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            cross_origin::guard,
        ))
        .layer(TraceLayer::new_for_http())
        .with_state(state)
}

async fn not_found(uri: axum::http::Uri) -> AppError {
    AppError::not_found(
        "not_found",
        format!("nothing is served at {}; see /docs for the API", uri.path()),
    )
}

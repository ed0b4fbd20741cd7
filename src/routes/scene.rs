//! `GET /scene?bbox=` and `GET /scene.glb?bbox=`: the mesh of an area (or, from `/scene`, its
//! statistics as JSON).

use super::params::{BboxQuery, EncodingParam, HeightBaseParam, mesh_options, parse_bbox};
use super::roofs::{ChosenRoofs, generate_with_roofs, scene_response};
use super::scene_stats::SceneStats;
use super::schemas::GlbBytes;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::{Generated, MeshOptions, RoofsParam};
use crate::state::AppState;
use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use citymesh_core::mesh::Encoding;
use citymesh_core::scene::SceneArea;
use serde::Deserialize;
use utoipa::{IntoParams, ToSchema};

/// Scenes cut at their box change only when their data does; they are not cached here.
const SCENE_CACHE_CONTROL: &str = "public, max-age=300";

/// What `/scene` answers with.
#[derive(Debug, Clone, Copy, Deserialize, ToSchema, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SceneFormat {
    /// Binary glTF, the same bytes as `/scene.glb`.
    Glb,
    /// The statistics `/scene/stats` gives.
    Json,
}

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct SceneQuery {
    /// The area as `minLon,minLat,maxLon,maxLat` in WGS84 degrees, e.g. `8.400,49.010,8.409,49.017`
    /// (the demo city). Latitudes within ±85.0511; the area may not exceed the server's limit (25 km²
    /// by default).
    #[param(
        required = true,
        pattern = r"^\s*-?[0-9.eE+-]+\s*(,\s*-?[0-9.eE+-]+\s*){3}$",
        example = "8.400,49.010,8.409,49.017"
    )]
    pub bbox: Option<String>,
    /// `glb` (the default) or `json`. Without it, the `Accept` header chooses: `json` when it
    /// gives `application/json` a higher quality than `model/gltf-binary`.
    #[param(inline)]
    pub format: Option<SceneFormat>,
    /// Where roof shapes come from: `osm` (the default), `classified` or `inferred`.
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
    /// How the GLB stores vertices: `plain` (the default), `quantized` or `meshopt`; see
    /// `/scene.glb`.
    #[param(inline)]
    pub encoding: Option<EncodingParam>,
    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings; the default unless the server says otherwise) or `highest` (the paper's rule).
    #[param(inline)]
    pub height_base: Option<HeightBaseParam>,
}

/// The mesh of a bounding box (binary glTF), or its statistics (JSON).
///
/// The same scene as `/scene.glb`, byte for byte, by default. With `format=json` (or
/// `Accept: application/json`), the figures `/scene/stats` gives for the same box.
#[utoipa::path(get, path = "/scene", tag = "meshes", params(SceneQuery),
    responses(
        (status = 200, description = "The scene, or its statistics", content(
            (inline(GlbBytes) = "model/gltf-binary"),
            (SceneStats = "application/json"),
        )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "The bbox is missing, malformed, inverted, out of range or too large, or the format is unknown", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn scene(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    query: Result<Query<SceneQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let format = query.format.unwrap_or_else(|| negotiate(&request_headers));
    let mesh = mesh_options(
        &state,
        query.encoding,
        &request_headers,
        Encoding::Plain,
        query.height_base,
    );
    let generated = generate_box(&state, query.bbox.as_deref(), query.roofs, mesh).await?;
    Ok(match format {
        SceneFormat::Glb => scene_response(&request_headers, generated, SCENE_CACHE_CONTROL),
        SceneFormat::Json => {
            let mut response = Json(SceneStats::of(&generated.0, &generated.1)).into_response();
            // The same URL answers GLB or JSON by the Accept header: caches must key on it.
            response
                .headers_mut()
                .insert(header::VARY, axum::http::HeaderValue::from_static("accept"));
            response
        }
    })
}

/// JSON when the client prefers JSON to binary glTF by the `Accept` header's quality values.
fn negotiate(request: &HeaderMap) -> SceneFormat {
    if super::accept::prefers(request, "application/json", super::headers::GLB) {
        SceneFormat::Json
    } else {
        SceneFormat::Glb
    }
}

/// Generates the box scene of a `bbox` parameter, with roofs as asked.
async fn generate_box(
    state: &AppState,
    bbox: Option<&str>,
    roofs: Option<RoofsParam>,
    mesh: MeshOptions,
) -> Result<(Generated, ChosenRoofs), AppError> {
    let bbox = parse_bbox(bbox, &state.generator.limits)?;
    generate_with_roofs(
        state,
        SceneArea::Bbox(bbox),
        roofs.unwrap_or_default(),
        mesh,
    )
    .await
}

/// The mesh of a bounding box as binary glTF: the ground and the buildings of the server's OSM
/// data, cut at the box border.
///
/// Positions are metres in a local east-north-up frame whose origin (the box centre at 0 m above
/// sea level) is stored in `scenes[0].extras.origin`; glTF axes are x = east, y = up, z = -north.
/// The response headers `X-Citymesh-*` give the generation time, vertex and triangle counts, and
/// whether the ground came from the DEM or the flat 0 m fallback, and the building figures that
/// `/scene/stats` gives in full.
#[utoipa::path(get, path = "/scene.glb", tag = "meshes", params(BboxQuery),
    responses(
        (status = 200, description = "The scene", content_type = "model/gltf-binary", body = inline(GlbBytes),
            headers(
                ("X-Citymesh-Generation-Ms" = f64, description = "Generation time in milliseconds (of the generation that made it, when it came from the scene cache)"),
                ("X-Citymesh-Cache" = String, description = "`hit` (box scenes with roofs from tags are kept in memory, shared with `/scene` and `/scene/stats`) or `miss`"),
                ("X-Citymesh-Vertices" = u64, description = "Vertices in the file"),
                ("X-Citymesh-Triangles" = u64, description = "Triangles in the file"),
                ("X-Citymesh-Void-Cells" = u64, description = "Ground cells left empty by DEM voids"),
                ("X-Citymesh-Ground" = String, description = "`dem`, or `flat-fallback; missing=N49E008,...`"),
                ("X-Citymesh-Osm" = String, description = "Where the buildings came from: `files`, `stored`, or `missing=14/x/y (offline: no buildings there)`"),
                ("ETag" = String, description = "Strong validator of the bytes"),
                ("X-Citymesh-Buildings" = u64, description = "Buildings and building parts generated"),
                ("X-Citymesh-Buildings-Skipped" = String, description = "`0`, or the count and reasons, e.g. `2; self_intersecting=2`"),
                ("X-Citymesh-Flat-Roofs-Percent" = f64, description = "Share of flat roofs (paper Tables 2 and 3)"),
                ("X-Citymesh-Roof-Shapes-From-Tags-Percent" = f64, description = "Share of roof shapes taken from `roof:shape` tags rather than defaults"),
                ("X-Citymesh-Roofs" = String, description = "With `roofs=classified`: `classified, N` or `partial, N pending`; with `roofs=inferred`: `inferred, N`"),
            )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "The bbox is missing, malformed, inverted, out of range or too large", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn scene_glb(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    query: Result<Query<BboxQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let mesh = mesh_options(
        &state,
        query.encoding,
        &request_headers,
        Encoding::Plain,
        query.height_base,
    );
    let generated = generate_box(&state, query.bbox.as_deref(), query.roofs, mesh).await?;
    Ok(scene_response(
        &request_headers,
        generated,
        SCENE_CACHE_CONTROL,
    ))
}

//! `GET /scene.glb?bbox=`: the mesh of an area.

use super::conditional::generated_response;
use crate::error::{AppError, ErrorBody};
use crate::generate::{Area, generate};
use crate::state::AppState;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;
use citymesh_core::geo::GeoBbox;
use serde::Deserialize;
use utoipa::IntoParams;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct SceneQuery {
    /// The area as `minLon,minLat,maxLon,maxLat` in WGS84 degrees, e.g. `8.39,49.04,8.41,49.06`.
    /// Latitudes within ±85.0511; the area may not exceed the server's limit (25 km² by default).
    pub bbox: Option<String>,
}

/// The mesh of a bounding box as binary glTF: the ground and the buildings of the server's OSM
/// data, cut at the box border.
///
/// Positions are metres in a local east-north-up frame whose origin (the box centre at 0 m above
/// sea level) is stored in `scenes[0].extras.origin`; glTF axes are x = east, y = up, z = -north.
/// The response headers `X-Citymesh-*` give the generation time, vertex and triangle counts, and
/// whether the ground came from the DEM or the flat 0 m fallback, and the building figures that
/// `/scene/stats` gives in full.
#[utoipa::path(get, path = "/scene.glb", tag = "meshes", params(SceneQuery),
    responses(
        (status = 200, description = "The scene", content_type = "model/gltf-binary", body = Vec<u8>,
            headers(
                ("X-Citymesh-Generation-Ms" = f64, description = "Generation time in milliseconds"),
                ("X-Citymesh-Vertices" = u64, description = "Vertices of the generated mesh"),
                ("X-Citymesh-Triangles" = u64, description = "Triangles of the generated mesh"),
                ("X-Citymesh-Void-Cells" = u64, description = "Ground cells left empty by DEM voids"),
                ("X-Citymesh-Ground" = String, description = "`dem`, or `flat-fallback; missing=N49E008,...`"),
                ("X-Citymesh-Osm" = String, description = "Where the buildings came from: `files`, `stored`, or `missing=14/x/y (offline: no buildings there)`"),
                ("ETag" = String, description = "Strong validator of the bytes"),
                ("X-Citymesh-Buildings" = u64, description = "Buildings and building parts generated"),
                ("X-Citymesh-Buildings-Skipped" = String, description = "`0`, or the count and reasons, e.g. `2; self_intersecting=2`"),
                ("X-Citymesh-Flat-Roofs-Percent" = f64, description = "Share of flat roofs (paper Tables 2 and 3)"),
                ("X-Citymesh-Roof-Shapes-From-Tags-Percent" = f64, description = "Share of roof shapes taken from `roof:shape` tags rather than defaults"),
            )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "The bbox is missing, malformed, inverted, out of range or too large", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn scene_glb(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    query: Result<Query<SceneQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let bbox = parse_bbox(query.bbox.as_deref(), state.limits.max_bbox_km2)?;
    let generated = generate(&state, Area::Scene(bbox)).await?;
    Ok(generated_response(
        &request_headers,
        generated,
        "public, max-age=300",
    ))
}

/// Checks a `bbox` parameter against the format and the area limit.
pub(crate) fn parse_bbox(text: Option<&str>, max_km2: f64) -> Result<GeoBbox, AppError> {
    let text = text.ok_or_else(|| {
        AppError::bad_request(
            "missing_bbox",
            "add ?bbox=minLon,minLat,maxLon,maxLat, e.g. ?bbox=8.39,49.04,8.41,49.06",
        )
    })?;
    let bbox: GeoBbox = text
        .parse()
        .map_err(|e| AppError::bad_request("invalid_bbox", format!("bbox: {e}")))?;
    let area = bbox.area_km2();
    if area > max_km2 {
        return Err(AppError::bad_request(
            "bbox_too_large",
            format!(
                "the bbox covers {area:.2} km², more than this server's limit of {max_km2} km²: request a smaller area or tiles"
            ),
        ));
    }
    Ok(bbox)
}

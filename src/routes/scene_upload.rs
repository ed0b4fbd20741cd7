//! `POST /scene.glb`: the mesh of the user's own building definitions, a GeoJSON
//! FeatureCollection, built by the same generator as OSM data and placed on the DEM where one
//! covers it. This is how a user fixes a wrong roof shape in real data and rebuilds.

use super::conditional::generated_response;
use super::params::{HeightBaseParam, heights_for};
use super::schemas::GlbBytes;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::{Buildings, MeshOptions, generate, run_blocking};
use crate::state::AppState;
use axum::body::Body;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::Response;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::GeoBbox;
use citymesh_core::geojson::{GeoJsonErrorKind, read_geojson};
use citymesh_core::mesh::Encoding;
use citymesh_core::scene::SceneArea;
use std::sync::Arc;

/// The query of `POST /scene.glb`.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub struct UploadQuery {
    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings; the default unless the server says otherwise) or `highest` (the paper's rule).
    #[param(inline)]
    pub height_base: Option<HeightBaseParam>,
}

/// Ground around the buildings when the collection has no `bbox`, metres.
const MARGIN_M: f64 = 20.0;

fn document(status: StatusCode, code: &'static str, detail: String) -> AppError {
    AppError::Document {
        status,
        code,
        detail,
        feature: None,
        field: None,
    }
}

/// The mesh of posted building definitions.
///
/// Send a GeoJSON FeatureCollection (`Content-Type: application/geo+json` or
/// `application/json`) of Polygon and MultiPolygon features, holes allowed, with OSM-style
/// properties: `height`, `min_height`, `building:levels`, `roof:shape` (every shape of Simple 3D
/// Buildings: flat, gabled, hipped, pyramidal, skillion, half-hipped, gambrel, mansard, saltbox,
/// double_saltbox, quadruple_saltbox, side_hipped, side_half-hipped, sawtooth, crosspitched,
/// round, dome, onion, cone, frustum; `many` and `complex` draw the outline flat), `roof:height`,
/// `roof:orientation`,
/// `roof:direction`, `building:colour`, `roof:colour`, `building:part`. The collection's `bbox`
/// (if given) is the scene's extent; otherwise the features' extent plus 20 m. Errors name the
/// feature index and the field.
#[utoipa::path(post, path = "/scene.glb", tag = "meshes", params(UploadQuery),
    request_body(content = serde_json::Value, content_type = "application/geo+json",
        description = "A GeoJSON FeatureCollection of buildings"),
    responses(
        (status = 200, description = "The scene", content_type = "model/gltf-binary", body = inline(GlbBytes)),
        (status = 400, description = "The area is larger than the server's limit", body = ErrorBody),
        (status = 413, description = "The body, or its number of features or positions, is over the limit", body = ErrorBody),
        (status = 415, description = "Not sent as JSON", body = ErrorBody),
        (status = 422, description = "Not JSON, not a FeatureCollection, or a feature is invalid (the body names which and why)", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 503, description = "Every generation slot is busy, or generation took too long; see Retry-After", body = ErrorBody),
    ))]
pub async fn post_scene(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    query: Result<Query<UploadQuery>, QueryRejection>,
    body: Body,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let content_type = request_headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    // Media types are case-insensitive.
    let mime = content_type.split(';').next().unwrap_or("").trim();
    if !mime.eq_ignore_ascii_case("application/geo+json")
        && !mime.eq_ignore_ascii_case("application/json")
    {
        return Err(document(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            "unsupported_media_type",
            format!(
                "Content-Type '{content_type}' is not JSON: send the GeoJSON with Content-Type: application/geo+json"
            ),
        ));
    }
    let limit = state.max_upload_bytes;
    let bytes = axum::body::to_bytes(body, limit).await.map_err(|_| {
        document(
            StatusCode::PAYLOAD_TOO_LARGE,
            "too_large",
            format!(
                "the body is over this server's limit of {} MB (--max-upload-mb); split the collection",
                limit >> 20
            ),
        )
    })?;
    let limits = state.geojson_limits;
    let scene = run_blocking(&state.generator, move || {
        read_geojson(&bytes, limits).map_err(|e| {
            let (status, code) = match e.kind {
                GeoJsonErrorKind::TooLarge => (StatusCode::PAYLOAD_TOO_LARGE, "too_large"),
                GeoJsonErrorKind::NotJson => (StatusCode::UNPROCESSABLE_ENTITY, "not_json"),
                GeoJsonErrorKind::Invalid => (StatusCode::UNPROCESSABLE_ENTITY, "invalid_geojson"),
            };
            AppError::Document {
                status,
                code,
                detail: e.to_string(),
                feature: e.feature,
                field: Some(e.field),
            }
        })
    })
    .await?;
    if scene.records.is_empty() {
        return Err(document(
            StatusCode::UNPROCESSABLE_ENTITY,
            "invalid_geojson",
            "features: the collection has no feature; add at least one building".to_owned(),
        ));
    }
    let bbox = match scene.bbox {
        Some(b) => b,
        None => extent_with_margin(&scene.records).ok_or_else(|| {
            document(
                StatusCode::UNPROCESSABLE_ENTITY,
                "invalid_geojson",
                "features: their extent is not a valid area".to_owned(),
            )
        })?,
    };
    let km2 = bbox.area_km2();
    if km2 > state.generator.limits.max_bbox_km2 {
        return Err(AppError::bad_request(
            "bbox_too_large",
            format!(
                "the buildings span {km2:.2} km², more than this server's limit of {} km²",
                state.generator.limits.max_bbox_km2
            ),
        ));
    }
    let set = run_blocking(&state.generator, move || {
        Ok(Arc::new(BuildingSet::new(scene.records)))
    })
    .await?;
    let generated = generate(
        &state.generator,
        SceneArea::Given(bbox),
        Buildings::Given(set),
        None,
        MeshOptions {
            encoding: Encoding::Plain,
            heights: heights_for(&state, query.height_base),
            tags: Default::default(),
        },
    )
    .await?;
    Ok(generated_response(&request_headers, generated, "no-store"))
}

/// The features' extent grown by [`MARGIN_M`].
fn extent_with_margin(records: &[citymesh_core::osm::BuildingRecord]) -> Option<GeoBbox> {
    citymesh_core::building::cluster::records_extent(records).map(|b| b.grown_by_metres(MARGIN_M))
}

//! `GET /tiles/{z}/{x}/{y}.glb`: Web Mercator XYZ tiles, through the tile cache.

use super::params::{TileQuery, encoding_for, tile_query_of};
use super::roofs::cached_tile;
use super::schemas::GlbBytes;
use crate::cache::TileKey;
use crate::error::{AppError, ErrorBody};
use crate::state::AppState;
use axum::extract::rejection::PathRejection;
use axum::extract::{Path, RawQuery, Request, State};
use axum::response::Response;
use citymesh_core::geo::TileCoord;
use citymesh_core::mesh::Encoding;

/// One XYZ tile as binary glTF.
///
/// Each tile holds the ground clipped exactly to its bounds and, whole, the buildings whose
/// group (buildings that touch, an outline with its parts) has its representative point, the
/// centre of its bounding box, in the tile: every building lands in exactly one tile of a zoom
/// level and is never cut. Buildings may reach past the tile's edge. The local frame's origin (the
/// tile centre at 0 m above sea level) is stored in `scenes[0].extras.origin`. Zoom levels
/// outside the served range (12 to 20 by default) answer 404.
#[utoipa::path(get, path = "/tiles/{z}/{x}/{y}", tag = "meshes",
    params(
        ("z" = u8, Path, description = "Zoom level (the server serves 12 to 20 by default)", minimum = 0, maximum = 30, example = 16),
        ("x" = u32, Path, description = "Column, 0 at 180° W; below 2^z", minimum = 0, example = 34297),
        ("y" = u32, Path, description = "Row, 0 at 85.0511° N; below 2^z", minimum = 0, example = 22502),
        TileQuery,
    ),
    responses(
        (status = 200, description = "The tile", content_type = "model/gltf-binary", body = inline(GlbBytes),
            headers(
                ("X-Citymesh-Cache" = String, description = "`hit` (memory), `sqlite` (the on-disk cache) or `miss` (generated now)"),
                ("ETag" = String, description = "Strong validator of the bytes; send it back in If-None-Match"),
                ("Cache-Control" = String, description = "`public, max-age=3600`"),
                ("X-Citymesh-Roofs" = String, description = "With `roofs=classified`: `classified, N` (every untagged building has a prediction) or `partial, N pending`; with `roofs=inferred`: `inferred, N` (roofs the prior chose)"),
            )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "z, x or y is not a number or out of range", body = ErrorBody),
        (status = 404, description = "The zoom level is not served, or the format is not .glb", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn tile_glb(
    State(state): State<AppState>,
    path: Result<Path<(String, String, String)>, PathRejection>,
    RawQuery(query): RawQuery,
    // The whole request rather than a copy of its headers: this is the hottest route.
    request: Request,
) -> Result<Response, AppError> {
    let request_headers = request.headers();
    let Path((z, x, y)) = path.map_err(|e| AppError::bad_request("invalid_tile", e.body_text()))?;
    let tile = parse_tile(&z, &x, &y)?;
    let limits = state.generator.limits;
    if tile.z < limits.min_zoom || tile.z > limits.max_zoom {
        return Err(AppError::not_found(
            "zoom_not_served",
            format!(
                "zoom {} is not served: this server serves zoom {} to {}",
                tile.z, limits.min_zoom, limits.max_zoom
            ),
        ));
    }
    let asked = tile_query_of(query.as_deref())?;
    let encoding = encoding_for(asked.encoding, request_headers, Encoding::Plain);
    let key = TileKey::xyz(tile)
        .with_encoding(encoding)
        .with_tags(asked.tags());
    let roofs = asked.roofs.unwrap_or_default();
    cached_tile(&state, request_headers, key, roofs, TILE_CACHE_CONTROL).await
}

/// Tiles change only when their data does: clients may keep them an hour, then revalidate with
/// the ETag.
const TILE_CACHE_CONTROL: &str = "public, max-age=3600";

fn parse_tile(z: &str, x: &str, y: &str) -> Result<TileCoord, AppError> {
    let Some(y) = y.strip_suffix(".glb") else {
        return Err(AppError::not_found(
            "unknown_format",
            format!("'{y}': tiles are served as .glb, e.g. /tiles/16/34297/22502.glb"),
        ));
    };
    let number = |name: &str, text: &str| {
        text.parse::<u32>().map_err(|_| {
            AppError::bad_request(
                "invalid_tile",
                format!("{name} '{text}' is not a whole number ≥ 0"),
            )
        })
    };
    TileCoord::new(number("z", z)?, number("x", x)?, number("y", y)?)
        .map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))
}

//! 3D Tiles 1.1 for CesiumJS and 3d-tiles-renderer: `GET /3dtiles/tileset.json` (optionally
//! `?bbox=`), and the binary subtrees and ECEF glb content its implicit quadtree names, generated
//! on demand through the same caches as the XYZ tiles.

use super::conditional::cached_response;
use super::scene::parse_bbox;
use crate::error::{AppError, ErrorBody};
use crate::generate::{Area, generate, implicit_bbox};
use crate::osm::OsmSource;
use crate::state::AppState;
use axum::Json;
use axum::extract::rejection::{PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use citymesh_core::building::tags::parse_length;
use citymesh_core::geo::{GeoBbox, ImplicitTile, TileCoord};
use citymesh_core::tiles3d::{ImplicitLayout, tileset_json, write_subtree};
use serde::Deserialize;
use std::collections::HashSet;
use utoipa::IntoParams;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct TilesetQuery {
    /// The region as `minLon,minLat,maxLon,maxLat`; default: the extent of the served buildings
    /// (the demo city, or the `--osm` files). Required when buildings come from data tiles.
    pub bbox: Option<String>,
}

/// The region in a URL path, exactly as `GeoBbox` parses it back.
fn bbox_path(b: &GeoBbox) -> String {
    format!(
        "{},{},{},{}",
        b.min_lon(),
        b.min_lat(),
        b.max_lon(),
        b.max_lat()
    )
}

fn root_for(state: &AppState, text: Option<&str>) -> Result<GeoBbox, AppError> {
    if let Some(t) = text {
        return parse_bbox(Some(t), state.limits.max_bbox_km2);
    }
    match state.osm.as_ref() {
        OsmSource::Files(data) => data.set.extent().ok_or_else(|| {
            AppError::not_found(
                "no_buildings",
                "no buildings are loaded: give ?bbox=minLon,minLat,maxLon,maxLat",
            )
        }),
        OsmSource::Tiles(_) => Err(AppError::bad_request(
            "missing_bbox",
            "this server fetches OSM data by area: add ?bbox=minLon,minLat,maxLon,maxLat",
        )),
    }
}

/// The leaves at `leaf_level` that have content: those holding a cluster's representative point.
async fn content_leaves(
    state: &AppState,
    root: GeoBbox,
    leaf_level: u8,
) -> Result<HashSet<(u32, u32)>, AppError> {
    let buildings = state.osm.area(&root).await?;
    let leaves = tokio::task::spawn_blocking(move || {
        buildings
            .set
            .clusters_intersecting(&root)
            .iter()
            .map(|c| c.representative_point())
            .filter(|(lon, lat)| root.contains(*lon, *lat))
            .map(|(lon, lat)| {
                let t = ImplicitTile::containing(&root, leaf_level, lon, lat);
                (t.x, t.y)
            })
            .collect()
    })
    .await?;
    Ok(leaves)
}

/// The tree over a region with its height range from the DEM and the tallest building.
async fn layout(state: &AppState, root: GeoBbox) -> Result<ImplicitLayout, AppError> {
    let buildings = state.osm.area(&root).await?;
    let dem = state.dem.clone();
    let layout = tokio::task::spawn_blocking(move || {
        let model = dem.lookup(&root).model;
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for i in 0..=32 {
            for j in 0..=32 {
                let lon = root.min_lon() + (root.max_lon() - root.min_lon()) * f64::from(i) / 32.0;
                let lat = root.min_lat() + (root.max_lat() - root.min_lat()) * f64::from(j) / 32.0;
                let h = model.ground_height(lon, lat);
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        let set = &buildings.set;
        let tallest = set
            .clusters_intersecting(&root)
            .iter()
            .flat_map(|c| set.cluster_records(c))
            .filter_map(|r| r.tags.get("height").and_then(|h| parse_length(h)))
            .fold(60.0f64, f64::max);
        ImplicitLayout::new(root, lo - 20.0, hi + tallest + 20.0)
    })
    .await?;
    Ok(layout)
}

/// The region and tile of a `/3dtiles/area/{bbox}/.../{level}/{x}/{y}{ext}` path.
fn implicit_request(
    state: &AppState,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
    ext: &str,
) -> Result<(GeoBbox, ImplicitTile), AppError> {
    let Path((bbox, level, x, y)) =
        path.map_err(|e| AppError::bad_request("invalid_tile", e.body_text()))?;
    let root = parse_bbox(Some(&bbox), state.limits.max_bbox_km2)?;
    Ok((root, parse_implicit(&level, &x, &y, ext)?))
}

/// A 3D Tiles 1.1 tileset with implicit quadtree tiling over a region.
///
/// The root's bounding volume is a `region` (radians; heights from the DEM and the buildings);
/// each level halves it in longitude and latitude (y counted from the south); content (glb,
/// ECEF) sits at the deepest level, tiles of at most 400 m. Subtrees are binary.
#[utoipa::path(get, path = "/3dtiles/tileset.json", tag = "3d tiles", params(TilesetQuery),
    responses(
        (status = 200, description = "The tileset", body = serde_json::Value),
        (status = 400, description = "The bbox is malformed or too large, or needed and missing", body = ErrorBody),
    ))]
pub async fn tileset(
    State(state): State<AppState>,
    query: Result<Query<TilesetQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let root = root_for(&state, query.bbox.as_deref())?;
    let layout = layout(&state, root).await?;
    let json = tileset_json(&layout, &format!("area/{}/", bbox_path(&root)));
    Ok(([(header::CACHE_CONTROL, "public, max-age=300")], Json(json)).into_response())
}

fn parse_implicit(level: &str, x: &str, y: &str, ext: &str) -> Result<ImplicitTile, AppError> {
    let y = y.strip_suffix(ext).ok_or_else(|| {
        AppError::not_found("unknown_format", format!("'{y}' does not end in {ext}"))
    })?;
    let num = |name: &str, t: &str| {
        t.parse::<u32>().map_err(|_| {
            AppError::bad_request(
                "invalid_tile",
                format!("{name} '{t}' is not a whole number"),
            )
        })
    };
    let level = num("level", level)?;
    let t = ImplicitTile {
        level: u8::try_from(level).unwrap_or(u8::MAX),
        x: num("x", x)?,
        y: num("y", y)?,
    };
    if !t.is_valid() {
        return Err(AppError::not_found(
            "no_such_tile",
            format!("{level}/{}/{} is not a tile of the tree", t.x, t.y),
        ));
    }
    Ok(t)
}

/// A binary subtree file (the tree has one subtree, at the root).
#[utoipa::path(get, path = "/3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}.subtree", tag = "3d tiles",
    params(("bbox" = String, Path, description = "minLon,minLat,maxLon,maxLat"),
           ("level" = u8, Path), ("x" = u32, Path), ("y" = u32, Path)),
    responses(
        (status = 200, description = "The subtree", content_type = "application/octet-stream", body = Vec<u8>),
        (status = 404, description = "No such subtree", body = ErrorBody),
    ))]
pub async fn subtree(
    State(state): State<AppState>,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
) -> Result<Response, AppError> {
    let (root, t) = implicit_request(&state, path, ".subtree")?;
    if t != (ImplicitTile {
        level: 0,
        x: 0,
        y: 0,
    }) {
        return Err(AppError::not_found(
            "no_such_subtree",
            "this tree has one subtree, at 0/0/0",
        ));
    }
    let layout = layout(&state, root).await?;
    let leaf = layout.leaf_level;
    let leaves = content_leaves(&state, root, leaf).await?;
    let has_content = |t: ImplicitTile| {
        let shift = leaf - t.level.min(leaf);
        leaves
            .iter()
            .any(|&(x, y)| (x >> shift, y >> shift) == (t.x, t.y))
    };
    let bytes = write_subtree(
        t,
        layout.available_levels(),
        &|t| t.level == 0 || has_content(t),
        &|t| t.level == leaf && has_content(t),
        &|_| false,
    );
    Ok((
        [
            (header::CONTENT_TYPE, "application/octet-stream"),
            (header::CACHE_CONTROL, "public, max-age=300"),
        ],
        bytes,
    )
        .into_response())
}

/// A content tile: glb in ECEF (positions relative to a node translation, under the z-up to y-up
/// node matrix), the ground of the tile and its buildings.
#[utoipa::path(get, path = "/3dtiles/area/{bbox}/content/{level}/{x}/{y}.glb", tag = "3d tiles",
    params(("bbox" = String, Path, description = "minLon,minLat,maxLon,maxLat"),
           ("level" = u8, Path), ("x" = u32, Path), ("y" = u32, Path)),
    responses(
        (status = 200, description = "The content", content_type = "model/gltf-binary", body = Vec<u8>),
        (status = 404, description = "The tile has no content", body = ErrorBody),
    ))]
pub async fn content(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
) -> Result<Response, AppError> {
    let (root, tile) = implicit_request(&state, path, ".glb")?;
    let no_content = || {
        AppError::not_found(
            "no_content",
            "this tile has no content (see the subtree's availability)",
        )
    };
    if tile.level != ImplicitLayout::leaf_level_of(&root) {
        return Err(no_content());
    }
    implicit_bbox(&root, &tile)?;
    let key = TileCoord {
        z: tile.level,
        x: tile.x,
        y: tile.y,
    };
    // Cached content skips the availability check (errors are never cached).
    let (cached, level) = state
        .tiles
        .get_or_generate(&bbox_path(&root), key, || async {
            let leaves = content_leaves(&state, root, tile.level).await?;
            if !leaves.contains(&(tile.x, tile.y)) {
                return Err(no_content());
            }
            let g = generate(&state, Area::Implicit { root, tile }).await?;
            Ok((g.glb, g.stats))
        })
        .await?;
    Ok(cached_response(
        &request_headers,
        cached,
        level,
        "public, max-age=3600",
    ))
}

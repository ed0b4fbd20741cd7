//! 3D Tiles 1.1 for CesiumJS and 3d-tiles-renderer: `GET /3dtiles/tileset.json` (optionally
//! `?bbox=`, `?tiling=`), the ECEF glb content its quadtree names and, for implicit tiling, the
//! binary subtree; content goes through the same tile cache as XYZ tiles.

use super::params::{EncodingParam, TagsParam, TileQuery, encoding_for, parse_bbox, whole_number};
use super::roofs::cached_tile;
use super::schemas::{GlbBytes, SubtreeBytes};
use crate::cache::TileKey;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::{self, RoofsParam};
use crate::state::AppState;
use axum::Json;
use axum::extract::rejection::{PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use citymesh_core::geo::{GeoBbox, ImplicitTile};
use citymesh_core::mesh::Encoding;
use citymesh_core::tiles3d::{ImplicitLayout, Tiling, tileset_json};
use serde::Deserialize;
use utoipa::IntoParams;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct TilesetQuery {
    /// The region as `minLon,minLat,maxLon,maxLat`, for a tileset over that part alone;
    /// without it, the world tileset over everything the server holds.
    #[param(example = "8.400,49.010,8.409,49.017")]
    pub bbox: Option<String>,
    /// Where the content's roof shapes come from: `osm` (the default), `classified` or
    /// `inferred` (passed on to every content and subtree URI).
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
    /// How content tiles store vertices: `meshopt` (the default: quantized and compressed, which
    /// CesiumJS and 3d-tiles-renderer decode), `quantized` or `plain` (passed on to every content
    /// tile's URI).
    #[param(inline)]
    pub encoding: Option<EncodingParam>,
    /// How a tileset over a `bbox` lists its tiles: `explicit` (the default) or `implicit`
    /// (the world tileset is always explicit, in nested files).
    #[param(inline)]
    pub tiling: Option<TilingParam>,
    /// `all` gives each building one more property, `osm_tags`: every OSM tag of the element
    /// as a JSON object; `named` (the default) the named properties only (passed on to every
    /// content tile's URI).
    #[param(inline)]
    pub tags: Option<TagsParam>,
    /// The version of the content's data, as the world tileset names it in each content URI
    /// (16 hex digits): a URL with it never changes meaning, and is answered with
    /// `Cache-Control: public, max-age=31536000, immutable`; a version that is no longer the
    /// data's is 404 `stale_version` (fetch the tileset again). Without it, content is
    /// revalidated after a minute.
    #[param(example = "3f9c2a41d07be815")]
    pub v: Option<String>,
}

/// How a tileset lists its tiles, as asked with `?tiling=`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TilingParam {
    /// Every tile written out with the bounding region and geometric error measured on its
    /// content: every 3D Tiles client honours them.
    #[default]
    Explicit,
    /// A quadtree with one binary subtree that carries each tile's measured region and error as
    /// tile metadata (`TILE_BOUNDING_REGION`, `TILE_GEOMETRIC_ERROR`): smaller, and CesiumJS
    /// reads them, but 3d-tiles-renderer derives regions and errors from the root's and so
    /// misses content that reaches past a tile's square.
    Implicit,
}

impl From<TilingParam> for Tiling {
    fn from(t: TilingParam) -> Self {
        match t {
            TilingParam::Explicit => Tiling::Explicit,
            TilingParam::Implicit => Tiling::Implicit,
        }
    }
}

/// The query a content URI carries: what the tileset was asked for beyond the defaults.
pub(super) fn content_query(query: &TilesetQuery) -> String {
    let mut parts = Vec::new();
    match query.roofs.unwrap_or_default() {
        RoofsParam::Osm => {}
        RoofsParam::Classified => parts.push("roofs=classified".to_owned()),
        RoofsParam::Inferred => parts.push("roofs=inferred".to_owned()),
    }
    if let Some(e) = query.encoding
        && Encoding::from(e) != CONTENT_ENCODING
    {
        parts.push(format!("encoding={}", Encoding::from(e)));
    }
    if query.tags == Some(TagsParam::All) {
        parts.push("tags=all".to_owned());
    }
    parts.join("&")
}

/// Content tiles are meshopt unless asked otherwise: the smallest, and every 3D Tiles client
/// citymesh serves decodes it.
pub(super) const CONTENT_ENCODING: Encoding = Encoding::Meshopt;

/// The tree's root: the `bbox` given, else the extent of the served buildings.
fn root_for(state: &AppState, text: Option<&str>) -> Result<GeoBbox, AppError> {
    if let Some(t) = text {
        return parse_bbox(Some(t), &state.generator.limits);
    }
    let extent = state.generator.source.extent().ok_or_else(|| {
        AppError::bad_request(
            "missing_bbox",
            "this server fetches OSM data by area (or has none loaded): add \
             ?bbox=minLon,minLat,maxLon,maxLat",
        )
    })?;
    // The content URIs name the root: a root the content routes would refuse is refused here,
    // so a tileset never lists a URI that answers 400.
    parse_bbox(Some(&extent.to_string()), &state.generator.limits).map_err(|e| match e {
        AppError::BadRequest {
            code: "bbox_too_large",
            detail,
        } => AppError::bad_request(
            "bbox_too_large",
            format!(
                "the served buildings span {extent}, more than one tileset may cover: {detail}; \
                     add ?bbox=minLon,minLat,maxLon,maxLat for a part"
            ),
        ),
        other => other,
    })
}

/// The region and tile of a `/3dtiles/area/{bbox}/.../{level}/{x}/{y}{ext}` path.
fn implicit_request(
    state: &AppState,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
    ext: &str,
) -> Result<(GeoBbox, ImplicitTile), AppError> {
    let Path((bbox, level, x, y)) =
        path.map_err(|e| AppError::bad_request("invalid_tile", e.body_text()))?;
    let root = parse_bbox(Some(&bbox), &state.generator.limits)?;
    Ok((root, parse_implicit(&level, &x, &y, ext)?))
}

fn parse_implicit(level: &str, x: &str, y: &str, ext: &str) -> Result<ImplicitTile, AppError> {
    let y = y.strip_suffix(ext).ok_or_else(|| {
        AppError::not_found("unknown_format", format!("'{y}' does not end in {ext}"))
    })?;
    let level = whole_number("level", level)?;
    let t = ImplicitTile {
        level: u8::try_from(level).unwrap_or(u8::MAX),
        x: whole_number("x", x)?,
        y: whole_number("y", y)?,
    };
    if !t.is_valid() {
        return Err(AppError::not_found(
            "no_such_tile",
            format!("{level}/{}/{} is not a tile of the tree", t.x, t.y),
        ));
    }
    Ok(t)
}

/// A 3D Tiles 1.1 tileset: a quadtree over a region.
///
/// Each level halves the region in longitude and latitude (y counted from the south); content
/// (glb, ECEF) at every level: the leaves (tiles of at most 400 m) in full detail, coarser
/// levels simplified (small buildings left out, roofs flattened, a grid ground). Every tile's
/// bounding volume is a `region` (radians, metres) measured on its content, which may reach
/// past its square (a building belongs to one tile whole), with tight heights; its geometric
/// error is the largest height its content leaves out (0 at the leaves). With `tiling=explicit`
/// (the default) the tiles are written out; with `tiling=implicit` they are an implicit
/// quadtree whose one binary subtree carries each tile's region and error as tile metadata.
/// Without `bbox`, the region is the extent of the served buildings (the demo city, or the
/// `--osm` files); a server that fetches data by area needs it.
#[utoipa::path(get, path = "/3dtiles/tileset.json", tag = "3d tiles", params(TilesetQuery),
    responses(
        (status = 200, description = "The tileset (the world tileset with an ETag and `Cache-Control: public, max-age=60`)", body = Object),
        (status = 304, description = "Not modified: the If-None-Match ETag is current (the world tileset)"),
        (status = 400, description = "The bbox is malformed or too large, or needed and missing", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or the request took too long; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn tileset(
    State(state): State<AppState>,
    request_headers: axum::http::HeaderMap,
    query: Result<Query<TilesetQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    if query.bbox.is_none() {
        return super::world::world_tileset(&state, &request_headers, &query).await;
    }
    let root = root_for(&state, query.bbox.as_deref())?;
    let pitched = query.roofs.unwrap_or_default() != RoofsParam::Osm;
    let regions =
        pipeline::tile_regions(&state.generator, &state.tiles.regions, root, pitched).await?;
    let json = tileset_json(
        root,
        &regions,
        query.tiling.unwrap_or_default().into(),
        &format!("area/{root}/"),
        &content_query(&query),
    );
    Ok(([(header::CACHE_CONTROL, "public, max-age=300")], Json(json)).into_response())
}

/// A binary subtree file of an implicit tileset (the tree has one subtree, at the root).
#[utoipa::path(get, path = "/3dtiles/area/{bbox}/subtrees/{level}/{x}/{y}", tag = "3d tiles",
    params(("bbox" = String, Path, description = "The tree's region, minLon,minLat,maxLon,maxLat", example = "8.400,49.010,8.409,49.017"),
           ("level" = u8, Path, description = "Level of the subtree's root (only 0 exists)", minimum = 0, maximum = 30),
           ("x" = u32, Path, description = "Column at that level, from the west", minimum = 0),
           ("y" = u32, Path, description = "Row at that level, from the south", minimum = 0),
           TileQuery),
    responses(
        (status = 200, description = "The subtree", content_type = "application/octet-stream", body = inline(SubtreeBytes)),
        (status = 400, description = "The region or a coordinate is malformed, or the region too large", body = ErrorBody),
        (status = 404, description = "No such subtree, or the format is not .subtree", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or the request took too long; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn subtree(
    State(state): State<AppState>,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
    query: Result<Query<TileQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let (root, t) = implicit_request(&state, path, ".subtree")?;
    if (t.level, t.x, t.y) != (0, 0, 0) {
        return Err(AppError::not_found(
            "no_such_subtree",
            "this tree has one subtree, at 0/0/0",
        ));
    }
    // Regions hold pitched variants of untagged roofs for content with chosen roofs.
    let pitched = query.roofs.unwrap_or_default() != RoofsParam::Osm;
    let bytes = pipeline::subtree(&state.generator, &state.tiles.regions, root, pitched).await?;
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
#[utoipa::path(get, path = "/3dtiles/area/{bbox}/content/{level}/{x}/{y}", tag = "3d tiles",
    params(("bbox" = String, Path, description = "The tree's region, minLon,minLat,maxLon,maxLat", example = "8.400,49.010,8.409,49.017"),
           ("level" = u8, Path, description = "Level (every level has content; coarser above the leaves)", minimum = 0, maximum = 30),
           ("x" = u32, Path, description = "Column at that level, from the west", minimum = 0),
           ("y" = u32, Path, description = "Row at that level, from the south", minimum = 0),
           TileQuery),
    responses(
        (status = 200, description = "The content", content_type = "model/gltf-binary", body = inline(GlbBytes),
            headers(
                ("X-Citymesh-Cache" = String, description = "`hit` (memory), `sqlite` (the on-disk cache) or `miss` (generated now)"),
                ("ETag" = String, description = "Strong validator of the bytes; send it back in If-None-Match"),
                ("Cache-Control" = String, description = "`public, max-age=3600`"),
                ("X-Citymesh-Roofs" = String, description = "With `roofs=classified`: `classified, N` or `partial, N pending`; with `roofs=inferred`: `inferred, N`"),
            )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "The region or a coordinate is malformed, or the region too large", body = ErrorBody),
        (status = 404, description = "The tile is below the leaves, or the format is not .glb", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn content(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
    query: Result<Query<TileQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let (root, tile) = implicit_request(&state, path, ".glb")?;
    if tile.level > ImplicitLayout::leaf_level_of(&root) {
        return Err(AppError::not_found(
            "no_content",
            "this tile is below the tree's leaves (see the subtree's availability)",
        ));
    }
    // Errors (a tile without content among them) are never cached.
    let encoding = encoding_for(query.encoding, &request_headers, CONTENT_ENCODING);
    cached_tile(
        &state,
        &request_headers,
        TileKey::implicit(root, tile)
            .with_encoding(encoding)
            .with_tags(query.tags()),
        query.roofs.unwrap_or_default(),
        "public, max-age=3600",
    )
    .await
}

//! The world tileset: `GET /3dtiles/tileset.json` without a box, and the files its tree names
//! under `/3dtiles/world/{z}/{x}/{y}.json` (the tileset file whose root is that tile) and
//! `.glb` (its content). Every answer reads a bounded number of summaries: a tileset file at
//! most 85, a block tile one; a leaf (the buildings) at most the data tiles around one.

use super::params::{TileQuery, encoding_for, whole_number};
use super::roofs::cached_tile;
use super::schemas::GlbBytes;
use super::tiles3d::{CONTENT_ENCODING, TilesetQuery, content_query};
use crate::cache::TileKey;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::RoofsParam;
use crate::pipeline::world::{
    FILE_PREFIX, ROOT_PREFIX, block_buildings, block_content, root_extras, version_text, versioned,
};
use crate::state::AppState;
use axum::extract::rejection::{PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::Response;
use citymesh_core::geo::TileCoord;
use citymesh_core::tiles3d::{DATA_ZOOM, LEAF_ZOOM, world_tileset_json};

/// Content under a versioned URL (`?v=` the data's version): it never changes meaning.
const VERSIONED_CACHE_CONTROL: &str = "public, max-age=31536000, immutable";

/// Content and tileset files under URLs without a version: kept a minute, then revalidated
/// with the ETag (the data may follow a replication feed).
const SHORT_CACHE_CONTROL: &str = "public, max-age=60";

/// How long a client should wait for the summaries to be made.
const SUMMARIES_RETRY_SECS: u64 = 5;

/// The root tileset file of the world tree (`tileset.json` without a box).
pub async fn world_tileset(
    state: &AppState,
    request_headers: &HeaderMap,
    query: &TilesetQuery,
) -> Result<Response, AppError> {
    let store = crate::source::data_tiles::OsmTileStore::new(state.database.clone());
    let replication = store.replication_state().await?;
    tileset_file(
        state,
        request_headers,
        TileCoord { z: 0, x: 0, y: 0 },
        ROOT_PREFIX,
        &content_query(query),
        replication.as_ref(),
    )
}

/// A tileset file of the world tree whose root is `top`.
fn tileset_file(
    state: &AppState,
    request_headers: &HeaderMap,
    top: TileCoord,
    prefix: &str,
    query: &str,
    replication: Option<&crate::source::data_tiles::ReplicationState>,
) -> Result<Response, AppError> {
    let summaries = &state.summaries;
    if !summaries.is_ready() {
        let p = summaries.progress();
        return Err(AppError::Unavailable {
            code: "summaries_pending",
            detail: format!(
                "the world tileset is being summarised ({} of {} data tiles done); ask again \
                 shortly, or ask for a part with ?bbox=",
                p.done, p.data_tiles
            ),
            retry_after_secs: SUMMARIES_RETRY_SECS,
        });
    }
    // The root file says what the tree holds; the files below it only lead on.
    let extras = (prefix == ROOT_PREFIX).then(|| {
        root_extras(
            summaries.progress().data_tiles,
            summaries.get(&TileCoord { z: 0, x: 0, y: 0 }).as_deref(),
            replication,
        )
    });
    // Content versions (immutable URLs) only where the content depends on the data alone:
    // classified and inferred roofs change as predictions and priors come in.
    let versions = !query.contains("roofs=");
    let data_version = state.tiles.data_version();
    let lookup = |t: TileCoord| {
        summaries.world_tile(t).map(|w| {
            let mut w = versioned(w, data_version);
            if !versions {
                w.version = None;
            }
            w
        })
    };
    let json = world_tileset_json(top, &lookup, prefix, query, extras).ok_or_else(|| {
        AppError::not_found(
            "no_such_tile",
            format!(
                "{}/{}/{} holds no data: the tree only has tiles where buildings are",
                top.z, top.x, top.y
            ),
        )
    })?;
    let body = bytes::Bytes::from(
        serde_json::to_vec(&json).map_err(|e| AppError::Internal(e.to_string()))?,
    );
    let mut headers = HeaderMap::new();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    let etag = crate::cache::etag_header(None, &body);
    Ok(super::conditional::conditional_response(
        request_headers,
        body,
        etag,
        headers,
        SHORT_CACHE_CONTROL,
    ))
}

/// A tile of the world tree from its path: `{y}` ends in `.json` or `.glb`.
fn parse_world(
    path: Result<Path<(String, String, String)>, PathRejection>,
) -> Result<(TileCoord, &'static str), AppError> {
    let Path((z, x, y)) = path.map_err(|e| AppError::bad_request("invalid_tile", e.body_text()))?;
    let (y, ext) = if let Some(y) = y.strip_suffix(".json") {
        (y.to_owned(), "json")
    } else if let Some(y) = y.strip_suffix(".glb") {
        (y.to_owned(), "glb")
    } else {
        return Err(AppError::not_found(
            "unknown_format",
            format!("'{y}' ends neither in .json (a tileset file) nor in .glb (content)"),
        ));
    };
    let (z, x, y) = (
        whole_number("z", &z)?,
        whole_number("x", &x)?,
        whole_number("y", &y)?,
    );
    if z > u32::from(LEAF_ZOOM) {
        return Err(AppError::not_found(
            "no_such_tile",
            format!("zoom {z} is below the tree's leaves (zoom {LEAF_ZOOM})"),
        ));
    }
    let t =
        TileCoord::new(z, x, y).map_err(|e| AppError::not_found("no_such_tile", e.to_string()))?;
    Ok((t, ext))
}

/// A file of the world tileset: a tileset file (`.json`: the tile, the levels below it and
/// references to the next files, or every level down to the leaves from zoom 12) or a tile's content (`.glb`, ECEF: blocks from zoom 9 to 14,
/// the buildings themselves in full detail at zoom 15).
#[utoipa::path(get, path = "/3dtiles/world/{z}/{x}/{y}", tag = "3d tiles",
    params(("z" = u8, Path, description = "Zoom of the tile (Web Mercator, as XYZ tiles), 0 to 15", minimum = 0, maximum = 15),
           ("x" = u32, Path, description = "Column from the west", minimum = 0),
           ("y" = String, Path, description = "Row from the north, then `.json` (the tileset file whose root is this tile) or `.glb` (its content)", example = "5625.glb"),
           TileQuery),
    responses(
        (status = 200, description = "The tileset file (JSON) or the content (GLB)", content_type = "model/gltf-binary", body = inline(GlbBytes),
            headers(
                ("ETag" = String, description = "Strong validator of the content bytes"),
                ("Cache-Control" = String, description = "`public, max-age=31536000, immutable` for content under a current `?v=` version, else `public, max-age=60` (tileset files, content without `v`)"),
            )),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "A coordinate is malformed", body = ErrorBody),
        (status = 404, description = "No such tile (no data under it, or below the leaves), the name ends neither in .json nor .glb, or `stale_version`: the `?v=` version is no longer the data's (fetch the tileset again)", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "The summaries are still being made, Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn world_file(
    State(state): State<AppState>,
    request_headers: HeaderMap,
    path: Result<Path<(String, String, String)>, PathRejection>,
    query: Result<Query<TilesetQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let (tile, ext) = parse_world(path)?;
    if ext == "json" {
        return tileset_file(
            &state,
            &request_headers,
            tile,
            FILE_PREFIX,
            &content_query(&query),
            None,
        );
    }
    let Some(listed) = state.summaries.world_tile(tile) else {
        return Err(if state.summaries.is_ready() {
            AppError::not_found(
                "no_such_tile",
                format!("{}/{}/{} holds no data", tile.z, tile.x, tile.y),
            )
        } else {
            AppError::Unavailable {
                code: "summaries_pending",
                detail: "the world tileset is being summarised; ask again shortly".into(),
                retry_after_secs: SUMMARIES_RETRY_SECS,
            }
        });
    };
    if !listed.content {
        return Err(AppError::not_found(
            "no_content",
            "this tile has no content: it only leads to its children",
        ));
    }
    // A versioned URL is answered only while it names the data's version.
    let cache_control = match &query.v {
        None => SHORT_CACHE_CONTROL,
        Some(_) if query.roofs.is_some_and(|r| r != RoofsParam::Osm) => SHORT_CACHE_CONTROL,
        Some(v) => {
            let current = versioned(listed, state.tiles.data_version()).version;
            match current.map(version_text) {
                Some(c) if c == *v => VERSIONED_CACHE_CONTROL,
                Some(c) => {
                    return Err(AppError::not_found(
                        "stale_version",
                        format!(
                            "version {v} of {}/{}/{} is gone: its data changed (now {c}); \
                             fetch the tileset again for the current URLs",
                            tile.z, tile.x, tile.y
                        ),
                    ));
                }
                None => SHORT_CACHE_CONTROL,
            }
        }
    };
    let encoding = encoding_for(query.encoding, &request_headers, CONTENT_ENCODING);
    let key = TileKey::world(tile).with_encoding(encoding);
    if tile.z > DATA_ZOOM {
        let tags = query.tags.unwrap_or_default().into();
        let key = key.with_tags(tags);
        return cached_tile(
            &state,
            &request_headers,
            key,
            query.roofs.unwrap_or_default(),
            cache_control,
        )
        .await;
    }
    block_tile(&state, &request_headers, tile, key, cache_control).await
}

/// A tile of blocks, from its summary alone (roofs are flat whatever `roofs` asks).
async fn block_tile(
    state: &AppState,
    request_headers: &HeaderMap,
    tile: TileCoord,
    key: TileKey,
    cache_control: &'static str,
) -> Result<Response, AppError> {
    let summary = state
        .summaries
        .get(&tile)
        .ok_or_else(|| AppError::not_found("no_such_tile", "no data under this tile"))?;
    let ground = summary.ground_cells;
    let (cached, level) = state
        .tiles
        .get_or_generate(
            key,
            || block_buildings(summary),
            |buildings| async {
                let g =
                    block_content(&state.generator, tile, ground, buildings, key.encoding).await?;
                Ok::<_, AppError>((g.glb, g.stats))
            },
        )
        .await?;
    super::conditional::cached_response(request_headers, cached, level, cache_control).await
}

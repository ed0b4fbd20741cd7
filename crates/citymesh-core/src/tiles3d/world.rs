//! The world tileset: one explicit 3D Tiles tree over everything a server holds, on the Web
//! Mercator quadtree of the XYZ tiles and data tiles, written as nested tileset files of
//! [`LEVELS_PER_FILE`] levels each (external tilesets), so every file lists at most
//! 1 + 4 + 16 + 64 tiles whatever the area.
//!
//! - Zooms 0 to [`BLOCK_ZOOM`] - 1: no content, only the way down to where data is.
//! - [`BLOCK_ZOOM`] to [`DATA_ZOOM`] - 1: blocks made from the tile's summary (the buildings of a
//!   cell merged into one prism) on a coarse ground grid.
//! - [`DATA_ZOOM`] to [`LEAF_ZOOM`]: the buildings themselves, whole, on the DEM ground; roofs
//!   flattened above the leaves.
//!
//! A tile exists where data is (its summary exists), and the tiles below a data tile all exist
//! (ground where they hold no building). Each tile's region holds its content and its
//! descendants' (from the summaries, never from generating content); its geometric error is
//! what its content leaves out: half the largest roof rise for flattened roofs, half a block
//! cell's side (and the coarse ground's error) for blocks, the tile's width for tiles without
//! content (so a client always goes on into them), 0 at the leaves.

use super::summary::{BLOCK_ZOOM, DATA_ZOOM, LEAF_ZOOM, TileSummary};
use crate::building::feature::BUILDING_CLASS;
use crate::geo::{LocalFrame, Region, TileCoord};
use serde_json::{Value, json};

/// Levels a tileset file lists with content before it refers to the next files.
pub const LEVELS_PER_FILE: u8 = 3;

/// A tile of the world tree as a tileset lists it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldTile {
    pub region: Region,
    pub geometric_error: f64,
    /// Whether the tile has a content GLB.
    pub content: bool,
}

/// A tile's width in metres at its centre.
fn width_m(tile: &TileCoord) -> f64 {
    let b = tile.bounds();
    let (lon, lat) = b.center();
    let (mx, _) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
    (b.max_lon() - b.min_lon()) * mx
}

impl WorldTile {
    /// The tile `tile` as listed: `summary` is the tile's own for tiles at or above the data
    /// tiles, the data tile's above it for tiles below one.
    pub fn of(tile: TileCoord, summary: &TileSummary) -> Self {
        if tile.z > DATA_ZOOM {
            let error = if tile.z >= LEAF_ZOOM {
                0.0
            } else {
                summary.roof_error_m
            };
            return Self {
                region: summary.region_below(&tile),
                geometric_error: error,
                content: true,
            };
        }
        let geometric_error = if tile.z == DATA_ZOOM {
            summary.roof_error_m
        } else if summary.draws_blocks() {
            summary
                .block_error_m()
                .max(summary.ground_error_m)
                .max(summary.roof_error_m)
        } else {
            width_m(&tile)
        };
        Self {
            region: summary.region,
            geometric_error,
            content: tile.z >= BLOCK_ZOOM,
        }
    }
}

/// The four children of a tile, in the order tilesets list them.
pub fn children_of(t: &TileCoord) -> [TileCoord; 4] {
    [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| TileCoord {
        z: t.z + 1,
        x: 2 * t.x + dx,
        y: 2 * t.y + dy,
    })
}

/// The tileset file whose root is `top`: `top` and the levels below it down to
/// [`LEVELS_PER_FILE`] - 1 with their content, then the next files' roots as external
/// tilesets. `lookup` answers each tile that exists. `prefix` is put before every URI (the way
/// from this file's folder to the tree's: `../../` for `world/{z}/{x}/{y}.json`), `query` after
/// it. `None` when `top` does not exist.
pub fn world_tileset_json(
    top: TileCoord,
    lookup: &dyn Fn(TileCoord) -> Option<WorldTile>,
    prefix: &str,
    query: &str,
    extras: Value,
) -> Option<Value> {
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{query}")
    };
    let root_tile = lookup(top)?;
    let uri = |t: &TileCoord, ext: &str| format!("{prefix}{}/{}/{}.{ext}{query}", t.z, t.x, t.y);
    let mut root = listed(top, root_tile, &lookup, &uri, top.z + LEVELS_PER_FILE);
    root["refine"] = json!("REPLACE");
    let mut schema = BUILDING_CLASS.schema();
    schema["id"] = json!("citymesh_tileset");
    Some(json!({
        "asset": {
            "version": "1.1",
            "generator": concat!("citymesh ", env!("CARGO_PKG_VERSION")),
            "extras": extras,
        },
        "schema": schema,
        "geometricError": root_tile.geometric_error * 2.0,
        "root": root,
    }))
}

/// Tile `t` with its content and its children, down to `until`, where each existing tile is a
/// reference to its own file.
fn listed(
    t: TileCoord,
    tile: WorldTile,
    lookup: &dyn Fn(TileCoord) -> Option<WorldTile>,
    uri: &dyn Fn(&TileCoord, &str) -> String,
    until: u8,
) -> Value {
    let mut v = json!({
        "boundingVolume": {"region": tile.region.to_radians()},
        "geometricError": tile.geometric_error,
    });
    if tile.content {
        v["content"] = json!({"uri": uri(&t, "glb")});
    }
    if t.z >= LEAF_ZOOM {
        return v;
    }
    let children: Vec<Value> = children_of(&t)
        .into_iter()
        .filter_map(|c| Some((c, lookup(c)?)))
        .map(|(c, child)| {
            if c.z >= until {
                json!({
                    "boundingVolume": {"region": child.region.to_radians()},
                    "geometricError": child.geometric_error,
                    "content": {"uri": uri(&c, "json")},
                })
            } else {
                listed(c, child, lookup, uri, until)
            }
        })
        .collect();
    if !children.is_empty() {
        v["children"] = children.into();
    }
    v
}

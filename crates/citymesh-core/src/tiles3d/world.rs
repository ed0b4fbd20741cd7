//! The world tileset: one explicit 3D Tiles tree over everything a server holds, on the Web
//! Mercator quadtree of the XYZ tiles and data tiles, written as nested tileset files of
//! [`LEVELS_PER_FILE`] levels each, the last one down to the leaves (external tilesets;
//! [`next_file_zoom`]), so every file lists at most 1 + 4 + 16 + 64 tiles whatever the area.
//!
//! - Zooms 0 to [`BLOCK_ZOOM`] - 1: no content, only the way down to where data is.
//! - [`BLOCK_ZOOM`] to [`DATA_ZOOM`]: blocks made from the tile's summary (the buildings of a
//!   cell merged into one prism) on a coarse ground grid.
//! - [`LEAF_ZOOM`] (one level below the data tiles): the buildings themselves in full detail,
//!   whole, on the DEM ground.
//!
//! A tile exists where data is (its summary exists), and the tiles below a data tile all exist
//! (ground where they hold no building). Each tile's region holds its content and its
//! descendants' (from the summaries, never from generating content); its geometric error is
//! what its content leaves out: a block cell's diagonal (or the coarse ground's error, or half
//! the largest roof rise flattened, whichever is larger) for blocks, the tile's width for tiles without
//! content (so a client always goes on into them), 0 at the leaves.
//!
//! A server that fetches from Overpass may also cover an area it holds no data of yet
//! (`--world-area`): a tile there without a summary is *unfetched* ([`WorldTile::unfetched`]):
//! no content above the leaves, the errors of blocks (so a client goes down to the leaves only
//! where it would leave blocks), and a region that holds whatever its leaves fetch.

use super::summary::{BLOCK_CELLS, BLOCK_ZOOM, DATA_ZOOM, LEAF_ZOOM, TileSummary};
use crate::building::feature::BUILDING_CLASS;
use crate::geo::{GeoBbox, LocalFrame, Region, TileCoord};
use crate::osm::MAX_BUILDING_EXTENT_M;
use serde_json::{Value, json};

/// Levels a tileset file lists with content before it refers to the next files.
pub const LEVELS_PER_FILE: u8 = 3;

/// The zoom of the next files below a file whose root is at `z`: files start every
/// [`LEVELS_PER_FILE`] zooms from the root (0, 3, 6, 9, 12), and a file that would leave only
/// the leaves to the next ones lists them itself (the file of zoom 12 lists 12 to 15), so a
/// leaf is never a file of its own.
pub fn next_file_zoom(z: u8) -> u8 {
    let next = (z / LEVELS_PER_FILE + 1) * LEVELS_PER_FILE;
    if next >= LEAF_ZOOM {
        LEAF_ZOOM + 1
    } else {
        next
    }
}

/// A tile of the world tree as a tileset lists it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldTile {
    pub region: Region,
    pub geometric_error: f64,
    /// Whether the tile has a content GLB.
    pub content: bool,
    /// What its content is made from, as a number ([`TileSummary::content_version`]); `None`
    /// for a tile whose data is not fetched yet (its content will change).
    pub version: Option<u64>,
}

/// The lowest ground an unfetched tile's region reaches down to: below the lowest land (the
/// shore of the Dead Sea, about 430 m below sea level).
pub const UNFETCHED_FLOOR_M: f64 = -500.0;

/// The highest top an unfetched tile's region reaches up to: above the highest summit
/// (8,849 m) with the tallest building (828 m) on it.
pub const UNFETCHED_TOP_M: f64 = 9_700.0;

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
            return Self {
                region: summary.region_below(&tile),
                geometric_error: 0.0,
                content: true,
                version: Some(summary.content_version(&tile)),
            };
        }
        let geometric_error = if summary.draws_blocks() {
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
            version: Some(summary.content_version(&tile)),
        }
    }
}

impl WorldTile {
    /// A tile of the covered `area` that holds no fetched data (yet): the part of its square
    /// inside the area, grown by the largest building's extent (a leaf draws the groups whose
    /// representative point lies in it, whole), from the lowest ground to the highest top;
    /// content only at the leaves, which fetch their data tiles; the geometric error of blocks
    /// at zooms that draw them (a cell's diagonal), the tile's width above.
    pub fn unfetched(tile: TileCoord, area: &GeoBbox) -> Self {
        let b = tile.bounds();
        let square = Region {
            west: b.min_lon().max(area.min_lon()),
            south: b.min_lat().max(area.min_lat()),
            east: b.max_lon().min(area.max_lon()),
            north: b.max_lat().min(area.max_lat()),
            min_height: UNFETCHED_FLOOR_M,
            max_height: UNFETCHED_TOP_M,
        };
        let grown = square.grown(MAX_BUILDING_EXTENT_M);
        let region = Region {
            west: grown.west.max(-180.0),
            south: grown.south.max(-90.0),
            east: grown.east.min(180.0),
            north: grown.north.min(90.0),
            ..square
        };
        let geometric_error = if tile.z > DATA_ZOOM {
            0.0
        } else if tile.z >= BLOCK_ZOOM {
            width_m(&tile) / f64::from(BLOCK_CELLS) * std::f64::consts::SQRT_2
        } else {
            width_m(&tile)
        };
        Self {
            region,
            geometric_error,
            content: tile.z > DATA_ZOOM,
            version: None,
        }
    }

    /// This tile, over which `area` is covered, so that it may hold unfetched tiles below it:
    /// its region holds theirs too, and its error is at least theirs.
    pub fn covering_unfetched(self, tile: TileCoord, area: &GeoBbox) -> Self {
        let unfetched = Self::unfetched(tile, area);
        Self {
            region: self.region.union(&unfetched.region),
            geometric_error: self.geometric_error.max(unfetched.geometric_error),
            content: self.content,
            version: self.version,
        }
    }
}

/// The tile whose summary lists `t`: `t` itself at or above the data tiles, the data tile
/// holding it below them.
pub fn summary_tile(t: TileCoord) -> TileCoord {
    if t.z > DATA_ZOOM {
        let shift = t.z - DATA_ZOOM;
        TileCoord {
            z: DATA_ZOOM,
            x: t.x >> shift,
            y: t.y >> shift,
        }
    } else {
        t
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

/// The tileset file whose root is `top`: `top` and the levels below it down to the one above
/// [`next_file_zoom`] with their content, then the next files' roots as external
/// tilesets. `lookup` answers each tile that exists. `prefix` is put before every URI (the way
/// from this file's folder to the tree's: `../../` for `world/{z}/{x}/{y}.json`), `query` after
/// it; `extras` (the root file's) go in `asset`. `None` when `top` does not exist.
pub fn world_tileset_json(
    top: TileCoord,
    lookup: &dyn Fn(TileCoord) -> Option<WorldTile>,
    prefix: &str,
    query: &str,
    extras: Option<Value>,
) -> Option<Value> {
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{query}")
    };
    let root_tile = lookup(top)?;
    let uri = |t: &TileCoord, ext: &str| format!("{prefix}{}/{}/{}.{ext}{query}", t.z, t.x, t.y);
    let mut root = listed(top, root_tile, &lookup, &uri, next_file_zoom(top.z));
    root["refine"] = json!("REPLACE");
    let mut schema = BUILDING_CLASS.schema();
    schema["id"] = json!("citymesh_tileset");
    let mut asset = json!({
        "version": "1.1",
        "generator": concat!("citymesh ", env!("CARGO_PKG_VERSION")),
    });
    if let Some(extras) = extras {
        asset["extras"] = extras;
    }
    Some(json!({
        "asset": asset,
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
        // Content names the version of what it is made from, so its URL never changes meaning.
        let u = uri(&t, "glb");
        let u = match tile.version {
            Some(version) if u.contains('?') => format!("{u}&v={version:016x}"),
            Some(version) => format!("{u}?v={version:016x}"),
            None => u,
        };
        v["content"] = json!({ "uri": u });
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn files_start_where_a_file_ends_on_the_leaves() {
        let roots: Vec<u8> = std::iter::successors(Some(0u8), |&z| {
            Some(next_file_zoom(z)).filter(|&n| n <= LEAF_ZOOM)
        })
        .collect();
        assert_eq!(roots, [0, 3, 6, 9, 12]);
        // The last file lists its root and every level down to the leaves.
        assert_eq!(next_file_zoom(12), LEAF_ZOOM + 1);
        // A file asked for off the tree's roots still ends on one.
        assert_eq!(next_file_zoom(4), 6);
        assert_eq!(next_file_zoom(13), LEAF_ZOOM + 1);
    }
}

//! 3D Tiles 1.1 over a region's quadtree: the tileset JSON, explicit (every tile written out) or
//! implicit (with the binary subtree files that say which tiles exist and which have content),
//! each tile's bounding region and geometric error measured on its content ([`regions`]).
//! Content is GLB in ECEF ([`crate::scene::SceneArea::Implicit`]).

mod regions;
mod subtree;
mod summary;
mod summary_bytes;
mod tileset;
mod world;

pub use crate::geo::Region;
pub use regions::{TileRegions, measure_regions};
pub use subtree::{
    SUBTREE_MAGIC, TILE_CLASS, TILE_ERROR_PROPERTY, TILE_REGION_PROPERTY, root_subtree,
    write_subtree,
};
pub use summary::{BLOCK_CELLS, BLOCK_ZOOM, Block, DATA_ZOOM, LEAF_ZOOM, TileSummary};
pub use summary_bytes::SummaryBytesError;
pub use tileset::{ImplicitLayout, Tiling, tileset_json};
pub use world::{
    LEVELS_PER_FILE, WorldTile, children_of, next_file_zoom, summary_tile, world_tileset_json,
};

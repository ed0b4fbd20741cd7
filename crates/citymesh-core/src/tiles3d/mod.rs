//! 3D Tiles 1.1 with implicit tiling: the tileset JSON of a region and the binary subtree files
//! that say which tiles exist and which have content, with each tile's bounding region measured
//! on its content ([`regions`]). Content is GLB in ECEF
//! ([`crate::scene::SceneArea::Implicit`]).

mod regions;
mod subtree;
mod tileset;

pub use regions::{Region, TileRegions, measure_regions};
pub use subtree::{
    SUBTREE_MAGIC, TILE_CLASS, TILE_ERROR_PROPERTY, TILE_REGION_PROPERTY, root_subtree,
    write_subtree,
};
pub use tileset::{ImplicitLayout, tileset_json};

//! 3D Tiles 1.1 with implicit tiling: the tileset JSON of a region and the binary subtree files
//! that say which tiles exist and which have content. Content is GLB in ECEF
//! ([`crate::scene::SceneArea::Implicit`]).

mod subtree;
mod tileset;

pub use subtree::{SUBTREE_MAGIC, root_subtree, write_subtree};
pub use tileset::{ImplicitLayout, tileset_json};

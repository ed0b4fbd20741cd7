//! Generated content, cached twice: bytes in memory (moka, weighed in bytes) and in SQLite
//! ([`store`], surviving restarts), under typed keys ([`key`]). Concurrent requests for the same
//! tile share one lookup and one generation ([`tile_cache`]). Box scenes are kept in memory
//! with their figures ([`scene_cache`]), the tile regions of 3D Tiles trees ([`region_cache`]), the roof priors learned from each area's tags
//! ([`roof_priors`]). Changed data invalidates exactly
//! the content over the changed area, in both levels ([`invalidation`]). Cached entries are plain
//! bytes and an ETag string: HTTP types stay in `crate::routes`. Every in-memory cache has its
//! share of one memory budget ([`budget`]).

pub mod budget;
pub mod invalidation;
pub mod key;
mod pg_store;
mod region_cache;
mod roof_priors;
mod scene_cache;
mod store;
mod tile_cache;

pub use budget::MemoryBudget;
pub use key::{Encoding, Region, RoofSource, TileId, TileKey};
pub use pg_store::PgTileStore;
pub use region_cache::RegionCache;
pub use roof_priors::RoofPriors;
pub use scene_cache::{CachedScene, SceneCache};
pub use store::{StoredTile, TileStore};
pub use tile_cache::{CacheLevel, CachedTile, TileCache, etag_header, etag_of};

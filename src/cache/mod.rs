//! Generated content, cached twice: bytes in memory (moka, weighed in bytes) and in the database
//! ([`store`]: SQLite, or PostgreSQL shared by replicas; surviving restarts), under typed keys
//! ([`key`]). Concurrent requests for the same tile share one lookup and one generation
//! ([`tile_cache`]), across replicas too on PostgreSQL. Box scenes are kept in memory
//! with their figures ([`scene_cache`]), the tile regions of 3D Tiles trees ([`region_cache`]), the roof priors learned from each area's tags
//! ([`roof_priors`]). Changed data invalidates exactly
//! the content over the changed area, in both levels ([`invalidation`]); the world tileset's
//! content is kept gzip-compressed ([`content_coding`]), and other replicas drop
//! theirs when they hear of it ([`replica_invalidation`]). Cached entries are plain
//! bytes and an ETag string: HTTP types stay in `crate::routes`. Every in-memory cache has its
//! share of one memory budget ([`budget`]).

pub mod budget;
pub mod content_coding;
pub mod invalidation;
pub mod key;
mod region_cache;
pub mod replica_invalidation;
mod roof_priors;
mod scene_cache;
mod store;
mod summaries;
pub(crate) use summaries::{summarise_data_tile, summarise_parent};
mod tile_cache;

pub use budget::MemoryBudget;
pub use key::{Encoding, Region, RoofSource, TileId, TileKey};
pub use region_cache::{RegionCache, Stopped};
pub use roof_priors::{PRIORS_KEPT, RoofPriors};
pub use scene_cache::{CachedScene, SceneCache};
pub use store::{
    DATA_CHANGED_CHANNEL, DataChangedNote, GenerationLock, GenerationTurn, StoredTile, TileStore,
};
pub use summaries::{Summaries, SummaryProgress, keep_summaries};
pub use tile_cache::{CacheLevel, CachedTile, TileCache, etag_header, etag_of};

//! The tile regions of 3D Tiles trees kept in memory by the tree's region: they are measured on
//! all the tree's content, which costs as much as generating it, so once per region. The
//! tileset and its subtree are made from them. Invalidated with the tiles (changed data changes
//! the content's extent).

use citymesh_core::tiles3d::TileRegions;
use std::sync::Arc;

/// At most this many trees (each 48 bytes per tile).
const MAX_TREES: u64 = 64;

/// Tile regions by the tree's region (its `minLon,minLat,maxLon,maxLat` text) and whether
/// classified roofs were allowed for.
pub struct RegionCache {
    memory: moka::future::Cache<(String, bool), Arc<TileRegions>>,
}

impl Default for RegionCache {
    fn default() -> Self {
        Self {
            memory: moka::future::Cache::builder()
                .max_capacity(MAX_TREES)
                .build(),
        }
    }
}

impl RegionCache {
    /// The regions of `key`, measured by `make` when not held (concurrent requests share one).
    pub async fn get_or_make<F, E>(
        &self,
        key: (String, bool),
        make: F,
    ) -> Result<Arc<TileRegions>, E>
    where
        F: std::future::Future<Output = Result<Arc<TileRegions>, E>>,
        E: Clone + Send + Sync + 'static,
    {
        self.memory
            .try_get_with(key, make)
            .await
            .map_err(|e: std::sync::Arc<E>| (*e).clone())
    }

    /// Drops every tree's regions.
    pub fn invalidate_all(&self) {
        self.memory.invalidate_all();
    }
}

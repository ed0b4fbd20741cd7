//! Box scenes (`/scene`, `/scene.glb`, `/scene/stats`) kept in memory by their typed key, with
//! the figures of their generation, so repeated boxes (a viewer's statistics panel, a client
//! polling) cost a lookup instead of a generation. Memory only: a box is cheaper to regenerate
//! than a tile is to miss, and boxes are many. Invalidated with the tiles (see [`super::TileCache`]).

use super::key::TileKey;
use crate::generation_stats::GenerationStats;
use bytes::Bytes;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// A generated box scene: its GLB and what went into it.
#[derive(Clone, Debug)]
pub struct CachedScene {
    pub glb: Bytes,
    pub stats: Arc<GenerationStats>,
}

pub struct SceneCache {
    memory: moka::future::Cache<TileKey, CachedScene>,
    /// The tile cache's invalidation count: a scene generated while an invalidation ran is
    /// answered but not kept, as a tile is.
    epoch: Arc<AtomicU64>,
}

/// Bytes an entry costs beyond its GLB (figures, ids of skipped buildings, the entry).
const ENTRY_OVERHEAD: usize = 4_096;

impl SceneCache {
    pub fn new(memory_bytes: u64, epoch: Arc<AtomicU64>) -> Self {
        Self {
            epoch,
            memory: moka::future::Cache::builder()
                .max_capacity(memory_bytes)
                .weigher(|_, s: &CachedScene| {
                    u32::try_from(s.glb.len() + ENTRY_OVERHEAD).unwrap_or(u32::MAX)
                })
                .support_invalidation_closures()
                .build(),
        }
    }

    /// Bytes the scenes weigh now.
    pub async fn weighed_bytes(&self) -> u64 {
        self.memory.run_pending_tasks().await;
        self.memory.weighted_size()
    }

    /// The scene of `key` from memory (`true`), else `generate`d once however many ask at once
    /// (`false`). Errors are never cached.
    pub async fn get_or_generate<F, Fut, E>(
        &self,
        key: TileKey,
        generate: F,
    ) -> Result<(CachedScene, bool), E>
    where
        F: FnOnce() -> Fut,
        Fut: Future<Output = Result<(Bytes, GenerationStats), E>>,
        E: Clone + Send + Sync + 'static,
    {
        let mut generated = false;
        let started = self.epoch.load(Ordering::SeqCst);
        let scene = self
            .memory
            .try_get_with(key, async {
                generated = true;
                let (glb, stats) = generate().await?;
                Ok::<_, E>(CachedScene {
                    glb,
                    stats: Arc::new(stats),
                })
            })
            .await
            .map_err(|e: Arc<E>| (*e).clone())?;
        if generated && self.epoch.load(Ordering::SeqCst) != started {
            self.memory.invalidate(&key).await;
        }
        Ok((scene, !generated))
    }

    /// Drops the scenes whose box overlaps `area`.
    pub fn invalidate_area(&self, area: &citymesh_core::geo::GeoBbox) {
        let area = *area;
        if let Err(e) = self
            .memory
            .invalidate_entries_if(move |key, _| key.tile.bounds().intersects(&area))
        {
            tracing::error!("cannot invalidate cached scenes: {e}");
        }
    }

    pub fn invalidate_all(&self) {
        self.memory.invalidate_all();
    }
}

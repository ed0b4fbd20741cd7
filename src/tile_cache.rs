//! Generated tiles, cached twice: GLB bytes in memory (moka, weighed in bytes, bounded by
//! `--tile-cache-mb`) and in SQLite (they survive a restart). Concurrent requests for the same
//! tile share one lookup and one generation. A data change invalidates exactly the tiles over
//! the changed area, in both levels.

use crate::db::{TileKey, TileStore};
use crate::error::AppError;
use crate::metrics::Metrics;
use axum::http::HeaderValue;
use bytes::Bytes;
use citymesh_core::geo::{GeoBbox, TileCoord};
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

/// A tile ready to send: its bytes and their strong ETag.
#[derive(Clone, Debug)]
pub struct CachedTile {
    pub glb: Bytes,
    pub etag: HeaderValue,
    /// Generation figures, present when this request generated the tile.
    pub generated: Option<Arc<crate::generate::GenerationStats>>,
}

/// Where a tile was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CacheLevel {
    Memory,
    Sqlite,
    Generated,
}

impl CacheLevel {
    pub fn header(self) -> &'static str {
        match self {
            CacheLevel::Memory => "hit",
            CacheLevel::Sqlite => "sqlite",
            CacheLevel::Generated => "miss",
        }
    }
}

/// The strong ETag of some bytes.
pub fn etag_of(bytes: &[u8]) -> HeaderValue {
    let tag = format!("\"{:016x}\"", xxhash_rust::xxh3::xxh3_64(bytes));
    HeaderValue::from_str(&tag).unwrap_or_else(|_| HeaderValue::from_static("\"0\""))
}

/// The `(z, x0, x1, y0, y1)` tile ranges (inclusive) over `area` for each zoom in `zooms`.
pub fn tile_ranges(area: &GeoBbox, zooms: (u8, u8)) -> Vec<(u8, u32, u32, u32, u32)> {
    (zooms.0..=zooms.1)
        .map(|z| {
            let nw = TileCoord::containing(z, area.min_lon(), area.max_lat());
            let se = TileCoord::containing(z, area.max_lon(), area.min_lat());
            (z, nw.x, se.x, nw.y, se.y)
        })
        .collect()
}

/// Marks the SQLite variant of 3D Tiles content.
const IMPLICIT_MARK: &str = "-3dtiles-";

pub struct TileCache {
    /// Keyed by the tile scheme's area (empty for XYZ tiles; the region for 3D Tiles content)
    /// and the coordinate.
    memory: moka::future::Cache<(Arc<str>, TileCoord), CachedTile>,
    store: TileStore,
    /// Everything the bytes depend on besides the coordinate and the OSM data tiles (which
    /// invalidate explicitly): generator version, DEM files, local OSM files.
    variant: String,
    zooms: (u8, u8),
    metrics: Arc<Metrics>,
}

impl TileCache {
    pub fn new(
        store: TileStore,
        memory_bytes: u64,
        variant: String,
        zooms: (u8, u8),
        metrics: Arc<Metrics>,
    ) -> Self {
        let memory = moka::future::Cache::builder()
            .max_capacity(memory_bytes)
            .weigher(|_, t: &CachedTile| u32::try_from(t.glb.len()).unwrap_or(u32::MAX))
            .support_invalidation_closures()
            .build();
        Self {
            memory,
            store,
            variant,
            zooms,
            metrics,
        }
    }

    fn key(&self, area: &str, t: &TileCoord) -> TileKey {
        let variant = if area.is_empty() {
            self.variant.clone()
        } else {
            format!("{}{IMPLICIT_MARK}{area}", self.variant)
        };
        TileKey {
            z: t.z,
            x: t.x,
            y: t.y,
            variant,
        }
    }

    /// The tile from memory, else SQLite, else `generate` (run once however many ask at once).
    /// `area` tells tile schemes apart: empty for XYZ tiles, the region of 3D Tiles content.
    pub async fn get_or_generate<F, Fut>(
        &self,
        area: &str,
        tile: TileCoord,
        generate: F,
    ) -> Result<(CachedTile, CacheLevel), AppError>
    where
        F: FnOnce() -> Fut,
        Fut: Future<Output = Result<(Bytes, crate::generate::GenerationStats), AppError>>,
    {
        // 0: memory hit (the init below did not run), 1: SQLite, 2: generated.
        let level = AtomicU8::new(0);
        let result = self
            .memory
            .try_get_with((Arc::from(area), tile), async {
                let key = self.key(area, &tile);
                if let Some(glb) = self.store.get(&key).await? {
                    self.metrics.cache("memory", false);
                    self.metrics.cache("sqlite", true);
                    level.store(1, Ordering::Relaxed);
                    let etag = etag_of(&glb);
                    return Ok::<_, AppError>(CachedTile {
                        glb,
                        etag,
                        generated: None,
                    });
                }
                self.metrics.cache("memory", false);
                self.metrics.cache("sqlite", false);
                level.store(2, Ordering::Relaxed);
                let (glb, stats) = generate().await?;
                self.store.put(&key, &glb).await?;
                Ok(CachedTile {
                    etag: etag_of(&glb),
                    glb,
                    generated: Some(Arc::new(stats)),
                })
            })
            .await;
        let tile_value = result.map_err(|e: Arc<AppError>| (*e).clone())?;
        let level = match level.load(Ordering::Relaxed) {
            0 => {
                self.metrics.cache("memory", true);
                CacheLevel::Memory
            }
            1 => CacheLevel::Sqlite,
            _ => CacheLevel::Generated,
        };
        let tile_value = if level == CacheLevel::Generated {
            tile_value
        } else {
            CachedTile {
                generated: None,
                ..tile_value
            }
        };
        Ok((tile_value, level))
    }

    /// Drops every cached XYZ tile (any served zoom) that overlaps `area`, in memory and in
    /// SQLite, and all 3D Tiles content (its regions do not follow the XYZ grid; it is cheap to
    /// build again).
    pub async fn invalidate_area(&self, area: &GeoBbox) -> Result<u64, AppError> {
        let ranges = tile_ranges(area, self.zooms);
        let removed = self.store.delete_ranges(&ranges).await?
            + self.store.delete_variants_containing(IMPLICIT_MARK).await?;
        let ranges = Arc::new(ranges);
        let r = ranges.clone();
        if let Err(e) = self.memory.invalidate_entries_if(move |(scheme, t), _| {
            !scheme.is_empty()
                || r.iter().any(|&(z, x0, x1, y0, y1)| {
                    t.z == z && (x0..=x1).contains(&t.x) && (y0..=y1).contains(&t.y)
                })
        }) {
            tracing::error!("cannot invalidate cached tiles: {e}");
        }
        Ok(removed)
    }
}

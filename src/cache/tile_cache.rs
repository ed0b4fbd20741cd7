//! The two-level tile cache: memory, then the database (SQLite, or PostgreSQL shared by
//! replicas), then the generator, run once however many requests ask for the same tile at once
//! (across replicas too, on PostgreSQL).

use super::key::TileKey;
use super::region_cache::RegionCache;
use super::scene_cache::SceneCache;
use super::store::{GenerationLock, GenerationTurn, TileStore};
use crate::generation_stats::GenerationStats;
use crate::metrics::Metrics;
use axum::http::HeaderValue;
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use tokio_util::task::TaskTracker;

/// A tile ready to send: its bytes and their strong ETag (quoted, as a header value made once, so
/// answering from memory copies neither).
#[derive(Clone, Debug)]
pub struct CachedTile {
    pub bytes: Bytes,
    pub etag: HeaderValue,
    /// Generation figures, present when this request generated the tile.
    pub generated: Option<Arc<GenerationStats>>,
}

/// Where a tile was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CacheLevel {
    Memory,
    /// The database (`sqlite` or `postgres`).
    Stored(&'static str),
    Generated,
}

impl CacheLevel {
    /// The `X-Citymesh-Cache` value.
    pub fn name(self) -> &'static str {
        match self {
            CacheLevel::Memory => "hit",
            CacheLevel::Stored(backend) => backend,
            CacheLevel::Generated => "miss",
        }
    }
}

/// The strong ETag of some bytes, quoted as HTTP writes it.
pub fn etag_of(bytes: &[u8]) -> String {
    format!("\"{:016x}\"", xxhash_rust::xxh3::xxh3_64(bytes))
}

/// The ETag of `bytes` as a header value, taking `known` when it is one (a stored row's; a
/// damaged one is computed again).
pub fn etag_header(known: Option<&str>, bytes: &[u8]) -> HeaderValue {
    known
        .and_then(|e| HeaderValue::from_str(e).ok())
        .or_else(|| HeaderValue::from_str(&etag_of(bytes)).ok())
        // Quoted hex is always a valid header value: never reached.
        .unwrap_or_else(|| HeaderValue::from_static("\"0\""))
}

/// Bytes an entry costs beyond its tile's bytes (measured: about 1.1 KB).
const ENTRY_OVERHEAD: usize = 1_100;

pub struct TileCache {
    memory: moka::future::Cache<TileKey, CachedTile>,
    store: TileStore,
    /// Everything the bytes depend on besides the key and the OSM data tiles (which invalidate
    /// explicitly): generator version, DEM files, local OSM files.
    data_version: Arc<str>,
    metrics: Arc<Metrics>,
    /// Counts invalidations: a tile whose generation saw the count change may have been built
    /// from data that changed meanwhile, so it is served but not kept.
    epoch: Arc<AtomicU64>,
    /// Writes of generated tiles to the database, which run after the response left.
    writes: TaskTracker,
    /// How long a miss waits for another replica generating the same tile.
    lock_wait: std::time::Duration,
    /// Box scenes, in memory; invalidated with the tiles.
    pub scenes: SceneCache,
    /// The tile regions of 3D Tiles trees (measured on the content); invalidated with the
    /// tiles.
    pub regions: RegionCache<crate::error::AppError>,
}

impl TileCache {
    /// The data version its rows are made for (generator, DEM, source).
    pub fn data_version(&self) -> &str {
        &self.data_version
    }

    /// `memory_bytes` in all: three quarters for tiles, a quarter for box scenes.
    pub fn new(
        store: TileStore,
        memory_bytes: u64,
        data_version: String,
        metrics: Arc<Metrics>,
    ) -> Self {
        let memory = moka::future::Cache::builder()
            .max_capacity(memory_bytes / 4 * 3)
            // The bytes and what holding them costs besides (key, ETag, counters, moka's entry).
            .weigher(|_, t: &CachedTile| {
                u32::try_from(t.bytes.len() + ENTRY_OVERHEAD).unwrap_or(u32::MAX)
            })
            .support_invalidation_closures()
            .build();
        let epoch = Arc::new(AtomicU64::new(0));
        Self {
            memory,
            store,
            data_version: Arc::from(data_version),
            metrics,
            // A quarter for box scenes, which count the same invalidations.
            scenes: SceneCache::new(memory_bytes / 4, epoch.clone()),
            regions: RegionCache::default(),
            epoch,
            writes: TaskTracker::new(),
            lock_wait: std::time::Duration::from_secs(10),
        }
    }

    /// The kept summary of `tile` made for this data version (`None`: none, or unreadable).
    pub async fn kept_summary(
        &self,
        tile: citymesh_core::geo::TileCoord,
    ) -> Result<Option<citymesh_core::tiles3d::TileSummary>, sqlx::Error> {
        self.store.summary(tile, &self.data_version).await
    }

    /// Keeps `summaries` for this data version (`None`: the tile's row goes).
    pub async fn put_summaries(
        &self,
        summaries: &[(
            citymesh_core::geo::TileCoord,
            Option<&citymesh_core::tiles3d::TileSummary>,
        )],
    ) -> Result<(), sqlx::Error> {
        self.store
            .put_summaries(summaries, &self.data_version)
            .await
    }

    /// How long a miss waits for another replica generating the same tile before generating it
    /// too (10 s unless set).
    pub fn with_lock_wait(mut self, wait: std::time::Duration) -> Self {
        self.lock_wait = wait;
        self
    }

    /// `sqlite` or `postgres`: where tiles are stored.
    pub fn backend(&self) -> &'static str {
        self.store.backend()
    }

    /// Bytes the tiles and the box scenes in memory weigh now.
    pub async fn memory_use(&self) -> [(&'static str, u64); 2] {
        self.memory.run_pending_tasks().await;
        [
            ("tiles", self.memory.weighted_size()),
            ("scenes", self.scenes.weighed_bytes().await),
        ]
    }

    /// Waits until every write of a generated tile to SQLite has finished (at shutdown, and
    /// for callers that open the database next).
    pub async fn flush(&self) {
        self.writes.close();
        self.writes.wait().await;
        self.writes.reopen();
    }

    /// Writes a generated tile to SQLite after its response: a failed write is logged and
    /// counted, never a failed response. Not kept when the data changed since generation began.
    fn write_behind(
        &self,
        key: TileKey,
        bytes: Bytes,
        etag: String,
        epoch: u64,
        lock: Option<GenerationLock>,
    ) {
        let store = self.store.clone();
        let version = self.data_version.clone();
        let current = self.epoch.clone();
        let metrics = self.metrics.clone();
        self.writes.spawn(async move {
            if current.load(Ordering::SeqCst) != epoch {
                // Dropping the lock releases any replica waiting for it: it generates its own.
                return;
            }
            match store.put(&key, &version, &bytes, &etag, lock).await {
                Err(e) => {
                    metrics.tile_store_failures.inc();
                    tracing::warn!(error = %e, tile = ?key.tile, "generated tile not stored in SQLite (served all the same)");
                }
                // An invalidation ran while the row was written: it may not outlive it.
                Ok(()) if current.load(Ordering::SeqCst) != epoch => {
                    if let Err(e) = store.remove(&key, &version).await {
                        tracing::warn!(error = %e, "outdated tile not removed from SQLite");
                    }
                }
                Ok(()) => {}
            }
        });
    }

    /// The tile from memory, else the store, else `generate` on what `prepare` gathered (run
    /// once however many ask at once). `prepare` (gathering the data, which may wait on an
    /// upstream) runs before the generation turn is taken, so no database connection is held
    /// while it waits. Errors are never cached.
    pub async fn get_or_generate<P, PFut, T, F, Fut, E>(
        &self,
        key: TileKey,
        prepare: P,
        generate: F,
    ) -> Result<(CachedTile, CacheLevel), E>
    where
        P: FnOnce() -> PFut,
        PFut: Future<Output = Result<T, E>>,
        F: FnOnce(T) -> Fut,
        Fut: Future<Output = Result<(Bytes, GenerationStats), E>>,
        E: From<sqlx::Error> + Clone + Send + Sync + 'static,
    {
        // 0: memory hit (the init below did not run), 1: SQLite, 2: generated.
        let level = AtomicU8::new(0);
        // Set when the data changed while this tile was generated.
        let outdated = AtomicBool::new(false);
        // The invalidation epoch when this call started looking past memory (only set when it
        // does): a row read from SQLite just before an invalidation deleted it must not land in
        // memory after the invalidation cleared memory, any more than a tile generated meanwhile.
        let started = AtomicU64::new(u64::MAX);
        let result = self
            .memory
            .try_get_with(key, async {
                let epoch = self.epoch.load(Ordering::SeqCst);
                started.store(epoch, Ordering::SeqCst);
                // The database is a cache: when it cannot answer, the tile is generated.
                let stored = self
                    .store
                    .get(&key, &self.data_version)
                    .await
                    .unwrap_or_else(|e| {
                        tracing::warn!("tile store read failed, generating instead: {e}");
                        None
                    });
                let backend = self.backend();
                self.metrics.cache("memory", false);
                if let Some(stored) = stored {
                    self.metrics.cache(backend, true);
                    level.store(1, Ordering::Relaxed);
                    return Ok::<_, E>(CachedTile {
                        etag: etag_header(Some(&stored.etag), &stored.bytes),
                        bytes: stored.bytes,
                        generated: None,
                    });
                }
                self.metrics.cache(backend, false);
                // Gather first: a turn on PostgreSQL holds a connection until the tile is stored.
                let prepared = prepare().await?;
                // Another replica may be generating it: wait for its row rather than repeat it.
                let lock = match self
                    .store
                    .turn(&key, &self.data_version, self.lock_wait)
                    .await
                {
                    Ok(GenerationTurn::Stored { tile, waited }) => {
                        self.metrics.generation_lock_waits(waited, false);
                        level.store(1, Ordering::Relaxed);
                        return Ok(CachedTile {
                            etag: etag_header(Some(&tile.etag), &tile.bytes),
                            bytes: tile.bytes,
                            generated: None,
                        });
                    }
                    Ok(GenerationTurn::Generate {
                        lock,
                        waited,
                        timed_out,
                    }) => {
                        self.metrics.generation_lock_waits(waited, timed_out);
                        lock
                    }
                    Err(e) => {
                        tracing::warn!("generation lock not taken, generating all the same: {e}");
                        None
                    }
                };
                level.store(2, Ordering::Relaxed);
                let (bytes, stats) = generate(prepared).await?;
                let bytes = if key.kept_gzipped() {
                    let raw = bytes.clone();
                    // A failed compression (a panic) keeps the tile as it is: bytes say which.
                    tokio::task::spawn_blocking(move || super::content_coding::gzip(&raw))
                        .await
                        .unwrap_or(bytes)
                } else {
                    bytes
                };
                let etag = etag_of(&bytes);
                if self.epoch.load(Ordering::SeqCst) == epoch {
                    // Respond first: the row is written after.
                    self.write_behind(key, bytes.clone(), etag.clone(), epoch, lock);
                } else {
                    outdated.store(true, Ordering::SeqCst);
                }
                Ok(CachedTile {
                    etag: etag_header(Some(&etag), &bytes),
                    bytes,
                    generated: Some(Arc::new(stats)),
                })
            })
            .await;
        let tile = result.map_err(|e: Arc<E>| (*e).clone())?;
        let start = started.load(Ordering::SeqCst);
        if outdated.load(Ordering::SeqCst) {
            self.memory.invalidate(&key).await;
        } else if start != u64::MAX && self.epoch.load(Ordering::SeqCst) != start {
            // An invalidation ran between the start above and the tile landing in memory (or its
            // row in SQLite, after the invalidation's delete): neither copy may outlive it. The
            // tile is still served to this request, as when generation itself overlapped.
            self.memory.invalidate(&key).await;
            self.store.remove(&key, &self.data_version).await?;
        }
        let level = match level.load(Ordering::Relaxed) {
            0 => {
                self.metrics.cache("memory", true);
                CacheLevel::Memory
            }
            1 => CacheLevel::Stored(self.backend()),
            _ => CacheLevel::Generated,
        };
        // Only the request that generated the tile reports generation figures.
        let tile = if level == CacheLevel::Generated {
            tile
        } else {
            CachedTile {
                generated: None,
                ..tile
            }
        };
        Ok((tile, level))
    }

    /// Drops every cached tile whose ground overlaps `area`, in memory and in SQLite; answers
    /// how many stored tiles were deleted.
    pub async fn invalidate_area(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        self.epoch.fetch_add(1, Ordering::SeqCst);
        let removed = self.store.delete_overlapping(area).await?;
        self.invalidate_memory_area(area);
        Ok(removed)
    }

    /// Drops the tiles over `area` held in memory only: another replica changed the data and
    /// deleted the stored tiles already.
    pub fn invalidate_memory_area(&self, area: &GeoBbox) {
        self.epoch.fetch_add(1, Ordering::SeqCst);
        self.scenes.invalidate_area(area);
        self.regions.invalidate_all();
        let area = *area;
        if let Err(e) = self
            .memory
            .invalidate_entries_if(move |key, _| key.tile.bounds().intersects(&area))
        {
            tracing::error!("cannot invalidate cached tiles: {e}");
        }
    }

    /// Drops everything held in memory (a subscriber that missed announcements).
    pub fn invalidate_memory(&self) {
        self.epoch.fetch_add(1, Ordering::SeqCst);
        self.memory.invalidate_all();
        self.scenes.invalidate_all();
        self.regions.invalidate_all();
    }
}

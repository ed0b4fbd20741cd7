//! Where the buildings of an area come from: the `--osm` files held in memory, or data tiles
//! (SQLite, filled from Overpass or by `citymesh import`). Data tiles are parsed once and kept in
//! memory; concurrent requests for the same missing data tile make one upstream request; stale
//! tiles are served while a refresh runs; `--offline` never calls upstream.

use super::data_tile::{affected_area, data_tiles_for};
use super::files::OsmData;
use super::store::{DataSource, OsmTileStore, now_secs};
use crate::error::AppError;
use crate::metrics::{Metrics, UpstreamLabels};
use crate::tile_cache::TileCache;
use crate::upstream::{OverpassClient, OverpassError};
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, read_buildings};
use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// The buildings of an area and what they came from.
pub struct AreaBuildings {
    pub set: Arc<BuildingSet>,
    /// `files`, `stored`, or `missing=14/x/y,...` when offline data tiles had no data.
    pub origin: String,
}

pub enum OsmSource {
    /// `--osm` files, all in memory.
    Files(OsmData),
    /// Data tiles.
    Tiles(Arc<DataTileSource>),
}

impl OsmSource {
    /// The buildings an area needs.
    pub async fn area(&self, bbox: &GeoBbox) -> Result<AreaBuildings, AppError> {
        match self {
            OsmSource::Files(data) => Ok(AreaBuildings {
                set: data.set.clone(),
                origin: "files".to_owned(),
            }),
            OsmSource::Tiles(tiles) => tiles.area(bbox).await,
        }
    }

    /// Part of the generated tiles' cache key: changes when `--osm` files change. Data tiles
    /// invalidate the tiles they affect explicitly instead.
    pub fn fingerprint(&self) -> &str {
        match self {
            OsmSource::Files(data) => &data.fingerprint,
            OsmSource::Tiles(_) => "tiles",
        }
    }

    /// Buildings held in memory (files) or data tiles stored (tiles), for `/health`.
    pub fn summary(&self) -> usize {
        match self {
            OsmSource::Files(data) => data.set.records().len(),
            OsmSource::Tiles(t) => t.parsed.entry_count() as usize,
        }
    }
}

/// One parsed data tile.
struct ParsedDataTile {
    records: Vec<BuildingRecord>,
    /// False when offline and nothing is stored for it.
    present: bool,
    /// When it was fetched (Unix seconds), for data from Overpass; `None` for imported data,
    /// which is never refreshed.
    fetched_at: Option<i64>,
}

pub struct DataTileSource {
    store: OsmTileStore,
    upstream: Option<Arc<OverpassClient>>,
    ttl_secs: i64,
    parsed: moka::future::Cache<TileCoord, Arc<ParsedDataTile>>,
    sets: moka::future::Cache<Vec<TileCoord>, Arc<BuildingSet>>,
    refreshing: Arc<Mutex<HashSet<TileCoord>>>,
    metrics: Arc<Metrics>,
    tiles: Arc<TileCache>,
}

fn upstream_result(e: Option<&OverpassError>) -> UpstreamLabels {
    UpstreamLabels {
        result: e.map_or("ok", OverpassError::kind),
    }
}

impl DataTileSource {
    pub fn new(
        store: OsmTileStore,
        upstream: Option<Arc<OverpassClient>>,
        ttl_secs: i64,
        metrics: Arc<Metrics>,
        tiles: Arc<TileCache>,
    ) -> Arc<Self> {
        Arc::new(Self {
            store,
            upstream,
            ttl_secs,
            // Parsed records take roughly ten times the bytes of their count in kilobytes;
            // a few hundred data tiles cover a large city.
            parsed: moka::future::Cache::builder().max_capacity(512).build(),
            sets: moka::future::Cache::builder()
                .max_capacity(256)
                .support_invalidation_closures()
                .build(),
            refreshing: Arc::new(Mutex::new(HashSet::new())),
            metrics,
            tiles,
        })
    }

    async fn area(&self, bbox: &GeoBbox) -> Result<AreaBuildings, AppError> {
        let keys = data_tiles_for(bbox);
        let parsed =
            futures_util::future::try_join_all(keys.iter().map(|t| self.data_tile(*t))).await?;
        let missing: Vec<String> = keys
            .iter()
            .zip(&parsed)
            .filter(|(_, p)| !p.present)
            .map(|(t, _)| format!("{}/{}/{}", t.z, t.x, t.y))
            .collect();
        let set = self
            .sets
            .try_get_with(keys.clone(), async {
                let parsed = parsed.clone();
                tokio::task::spawn_blocking(move || {
                    let mut seen = HashSet::new();
                    let records: Vec<BuildingRecord> = parsed
                        .iter()
                        .flat_map(|p| &p.records)
                        .filter(|r| seen.insert(r.id))
                        .cloned()
                        .collect();
                    Arc::new(BuildingSet::new(records))
                })
                .await
                .map_err(AppError::from)
            })
            .await
            .map_err(|e: Arc<AppError>| (*e).clone())?;
        let origin = if missing.is_empty() {
            "stored".to_owned()
        } else {
            format!(
                "missing={} (offline: no buildings there)",
                missing.join(",")
            )
        };
        Ok(AreaBuildings { set, origin })
    }

    async fn data_tile(&self, t: TileCoord) -> Result<Arc<ParsedDataTile>, AppError> {
        let loaded = AtomicBool::new(false);
        let result = self
            .parsed
            .try_get_with(t, async {
                loaded.store(true, Ordering::Relaxed);
                self.metrics.cache("osm_memory", false);
                if let Some(stored) = self.store.get(&t).await? {
                    self.metrics.cache("osm_sqlite", true);
                    let fetched_at =
                        (stored.source == DataSource::Overpass).then_some(stored.fetched_at);
                    return parse(stored.body, fetched_at).await;
                }
                self.metrics.cache("osm_sqlite", false);
                let Some(upstream) = &self.upstream else {
                    return Ok(Arc::new(ParsedDataTile {
                        records: Vec::new(),
                        present: false,
                        fetched_at: None,
                    }));
                };
                let fetched = upstream.fetch_buildings(&t.bounds()).await;
                self.metrics
                    .upstream
                    .get_or_create(&upstream_result(fetched.as_ref().err()))
                    .inc();
                let body = fetched?;
                self.store.put(&t, &body, DataSource::Overpass).await?;
                parse(body.into(), Some(now_secs())).await
            })
            .await
            .map_err(|e: Arc<AppError>| (*e).clone());
        if !loaded.load(Ordering::Relaxed) {
            self.metrics.cache("osm_memory", true);
        }
        // Stale data is served now and refreshed in the background.
        if let Ok(p) = &result
            && p.fetched_at.is_some_and(|f| now_secs() - f > self.ttl_secs)
            && self.upstream.is_some()
        {
            self.start_refresh(t);
        }
        result
    }

    /// Refreshes a stale data tile in the background; the stale data is served meanwhile.
    fn start_refresh(&self, t: TileCoord) {
        let Ok(mut busy) = self.refreshing.lock() else {
            return;
        };
        if !busy.insert(t) {
            return;
        }
        drop(busy);
        let Some(upstream) = self.upstream.clone() else {
            return;
        };
        let (store, metrics, tiles) =
            (self.store.clone(), self.metrics.clone(), self.tiles.clone());
        let (parsed, sets) = (self.parsed.clone(), self.sets.clone());
        // The mark is cleared when the task ends, whatever happens.
        let done = RefreshDone(self.refreshing.clone(), t);
        tokio::spawn(async move {
            let fetched = upstream.fetch_buildings(&t.bounds()).await;
            metrics
                .upstream
                .get_or_create(&upstream_result(fetched.as_ref().err()))
                .inc();
            match fetched {
                Ok(body) => match store.put(&t, &body, DataSource::Overpass).await {
                    Ok(changed) if !changed => {
                        // Read back with its new fetch time, so it is not stale any more.
                        parsed.invalidate(&t).await;
                        tracing::debug!(tile = ?t, "OSM data refreshed, unchanged");
                    }
                    Ok(_) => {
                        parsed.invalidate(&t).await;
                        let _ = sets.invalidate_entries_if(move |k, _| k.contains(&t));
                        match tiles.invalidate_area(&affected_area(&t)).await {
                            Ok(n) => {
                                tracing::info!(tile = ?t, removed = n, "OSM data changed; tiles invalidated")
                            }
                            Err(e) => tracing::error!("cannot invalidate tiles: {e}"),
                        }
                    }
                    Err(e) => tracing::error!("cannot store refreshed OSM data: {e}"),
                },
                Err(e) => tracing::warn!(tile = ?t, "refresh failed, stale data kept: {e}"),
            }
            drop(done);
        });
    }
}

/// Clears a data tile's refresh mark when dropped.
struct RefreshDone(Arc<Mutex<HashSet<TileCoord>>>, TileCoord);

impl Drop for RefreshDone {
    fn drop(&mut self) {
        if let Ok(mut busy) = self.0.lock() {
            busy.remove(&self.1);
        }
    }
}

async fn parse(
    body: bytes::Bytes,
    fetched_at: Option<i64>,
) -> Result<Arc<ParsedDataTile>, AppError> {
    tokio::task::spawn_blocking(move || {
        read_buildings(&body)
            .map(|b| {
                Arc::new(ParsedDataTile {
                    records: b.buildings,
                    present: true,
                    fetched_at,
                })
            })
            .map_err(|e| AppError::internal(format!("stored OSM data unreadable: {e}")))
    })
    .await?
}

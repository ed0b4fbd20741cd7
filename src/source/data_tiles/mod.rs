//! OSM data tiles: buildings fetched and stored per Web Mercator tile of one fixed zoom
//! ([`data_tile`]), kept in SQLite ([`store`]) and filled from Overpass or by `citymesh import`
//! ([`import`]). Data tiles are parsed once and kept in memory; concurrent requests for the same
//! missing data tile make one upstream request; stale tiles are served while a refresh runs, and
//! a refresh that changes data announces the area; `--offline` never calls upstream.

pub mod data_tile;
pub mod import;
pub mod replication;
mod store;

pub use store::{DataOrigin, OsmTileStore, ReplicationState, StoredDataTile, content_hash};

use super::{
    AreaBuildings, BuildingSource, CHANGE_CAPACITY, DataChanged, PriorScope, SourceError,
    short_list, skips_near,
};
use crate::cache::budget::weight;
use crate::metrics::{Metrics, UpstreamLabels};
use crate::upstream::{OverpassClient, OverpassError};
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, Repaired, Skipped, read_buildings};
use data_tile::{MAX_DATA_TILES, affected_area, data_tiles_for};
use futures_util::future::BoxFuture;
use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::broadcast;

/// One parsed data tile.
struct ParsedDataTile {
    /// Shared with the building sets made of it.
    records: Vec<Arc<BuildingRecord>>,
    /// Buildings of the data tile that could not be built, and those built with less.
    skipped: Vec<Skipped>,
    repaired: Vec<Repaired>,
    /// False when offline and nothing is stored for it.
    present: bool,
    /// When it was fetched (Unix seconds), for data from Overpass; `None` for imported data,
    /// which is never refreshed.
    fetched_at: Option<i64>,
}

impl ParsedDataTile {
    /// Bytes it occupies, generously counted.
    fn byte_size(&self) -> usize {
        std::mem::size_of::<Self>()
            + self
                .records
                .iter()
                .map(|r| r.byte_size() + std::mem::size_of::<Arc<BuildingRecord>>())
                .sum::<usize>()
            + self.skipped.capacity() * std::mem::size_of::<Skipped>()
            + self.repaired.capacity() * std::mem::size_of::<Repaired>()
    }
}

/// Bytes of memory the parsed data tiles and the building sets may hold.
#[derive(Debug, Clone, Copy)]
pub struct DataTileMemory {
    pub parsed_bytes: u64,
    pub set_bytes: u64,
}

pub struct DataTileSource {
    store: OsmTileStore,
    upstream: Option<Arc<OverpassClient>>,
    ttl_secs: i64,
    /// Data tiles one request may fetch from upstream.
    calls_per_request: usize,
    parsed: moka::future::Cache<TileCoord, Arc<ParsedDataTile>>,
    sets: moka::future::Cache<Vec<TileCoord>, Arc<BuildingSet>>,
    refreshing: Arc<Mutex<HashSet<TileCoord>>>,
    /// Counts refreshes that replaced stored data. A parse or a building set made while one ran
    /// may hold the old data: it is answered, but not kept (moka would otherwise insert it after
    /// the refresh's invalidation).
    version: Arc<AtomicU64>,
    metrics: Arc<Metrics>,
    changes: broadcast::Sender<DataChanged>,
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
        calls_per_request: usize,
        memory: DataTileMemory,
        metrics: Arc<Metrics>,
    ) -> Arc<Self> {
        Arc::new(Self {
            store,
            upstream,
            ttl_secs,
            calls_per_request,
            parsed: moka::future::Cache::builder()
                .max_capacity(memory.parsed_bytes)
                .weigher(|_, p: &Arc<ParsedDataTile>| weight(p.byte_size()))
                .support_invalidation_closures()
                .build(),
            sets: moka::future::Cache::builder()
                .max_capacity(memory.set_bytes)
                .weigher(|k: &Vec<TileCoord>, s: &Arc<BuildingSet>| {
                    weight(s.byte_size() + k.capacity() * std::mem::size_of::<TileCoord>())
                })
                .support_invalidation_closures()
                .build(),
            refreshing: Arc::new(Mutex::new(HashSet::new())),
            version: Arc::new(AtomicU64::new(0)),
            metrics,
            changes: broadcast::channel(CHANGE_CAPACITY).0,
        })
    }

    /// The buildings of `bbox`'s data tiles; with `fetch`, those not held are fetched from
    /// upstream, else they count as empty (and that is not remembered: a later request may
    /// fetch them).
    async fn area(&self, bbox: &GeoBbox, fetch: bool) -> Result<AreaBuildings, SourceError> {
        let keys = data_tiles_for(bbox);
        if keys.len() > MAX_DATA_TILES {
            return Err(SourceError::AreaTooLarge {
                tiles: keys.len(),
                max: MAX_DATA_TILES,
            });
        }
        let version = self.version.load(Ordering::SeqCst);
        // Every data tile's future runs to its end (a fetch is never dropped half-way because
        // another failed), then the first failure is reported, upstream failures before the
        // request's call budget.
        let budget = AtomicUsize::new(self.calls_per_request);
        let results = futures_util::future::join_all(keys.iter().map(|t| async {
            if fetch {
                self.data_tile(*t, &budget).await
            } else {
                self.held_data_tile(*t, &budget).await
            }
        }))
        .await;
        let mut parsed = Vec::with_capacity(results.len());
        let mut failure: Option<SourceError> = None;
        for result in results {
            match result {
                Ok(p) => parsed.push(p),
                Err(e) => {
                    if failure
                        .as_ref()
                        .is_none_or(|f| matches!(f, SourceError::CallBudget { .. }))
                    {
                        failure = Some(e);
                    }
                }
            }
        }
        if let Some(e) = failure {
            return Err(e);
        }
        let missing: Vec<String> = keys
            .iter()
            .zip(&parsed)
            .filter(|(_, p)| !p.present)
            .map(|(t, _)| format!("{}/{}/{}", t.z, t.x, t.y))
            .collect();
        let assemble = || {
            let parsed = parsed.clone();
            async move {
                tokio::task::spawn_blocking(move || {
                    let mut seen = HashSet::new();
                    let records: Vec<Arc<BuildingRecord>> = parsed
                        .iter()
                        .flat_map(|p| &p.records)
                        .filter(|r| seen.insert(r.id))
                        .cloned()
                        .collect();
                    Arc::new(BuildingSet::from_shared(records))
                })
                .await
                .map_err(SourceError::from)
            }
        };
        // A set with data tiles counted empty only because they were not fetched is not kept
        // under the keys a fetching request would find it by.
        let set = if !fetch && !missing.is_empty() && self.upstream.is_some() {
            assemble().await?
        } else {
            self.sets
                .try_get_with(keys.clone(), assemble())
                .await
                .map_err(|e: Arc<SourceError>| (*e).clone())?
        };
        if self.version.load(Ordering::SeqCst) != version {
            self.sets.invalidate(&keys).await;
        }
        let origin = if missing.is_empty() {
            "stored".to_owned()
        } else {
            format!(
                "missing={} (offline: no buildings there)",
                short_list(&missing)
            )
        };
        // A building on a data-tile edge is in both tiles: report it once.
        let mut seen = HashSet::new();
        let skipped: Vec<Skipped> = parsed
            .iter()
            .flat_map(|p| &p.skipped)
            .filter(|s| seen.insert(s.id))
            .copied()
            .collect();
        let mut seen = HashSet::new();
        let repaired: Vec<Repaired> = parsed
            .iter()
            .flat_map(|p| &p.repaired)
            .filter(|r| seen.insert(r.id))
            .copied()
            .collect();
        Ok(AreaBuildings {
            set,
            origin,
            load_skips: skips_near(&skipped, bbox),
            repaired: Arc::new(repaired),
        })
    }

    /// A data tile as [`DataTileSource::data_tile`] reads it when it is held (stored or
    /// parsed already); one not held has no buildings here, and nothing is remembered of it.
    async fn held_data_tile(
        &self,
        t: TileCoord,
        budget: &AtomicUsize,
    ) -> Result<Arc<ParsedDataTile>, SourceError> {
        if self.upstream.is_none() || self.parsed.contains_key(&t) || self.store.holds(&t).await? {
            return self.data_tile(t, budget).await;
        }
        Ok(Arc::new(ParsedDataTile {
            records: Vec::new(),
            skipped: Vec::new(),
            repaired: Vec::new(),
            present: false,
            fetched_at: None,
        }))
    }

    async fn data_tile(
        &self,
        t: TileCoord,
        budget: &AtomicUsize,
    ) -> Result<Arc<ParsedDataTile>, SourceError> {
        let loaded = AtomicBool::new(false);
        let version = self.version.load(Ordering::SeqCst);
        let result = self
            .parsed
            .try_get_with(t, async {
                loaded.store(true, Ordering::Relaxed);
                self.metrics.cache("osm_memory", false);
                if let Some(stored) = self.store.get(&t).await? {
                    self.metrics.cache("osm_sqlite", true);
                    let fetched_at =
                        (stored.origin == DataOrigin::Overpass).then_some(stored.fetched_at);
                    return parse(stored.body, fetched_at).await;
                }
                self.metrics.cache("osm_sqlite", false);
                let Some(upstream) = &self.upstream else {
                    return Ok(Arc::new(ParsedDataTile {
                        records: Vec::new(),
                        skipped: Vec::new(),
                        repaired: Vec::new(),
                        present: false,
                        fetched_at: None,
                    }));
                };
                if budget
                    .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |b| b.checked_sub(1))
                    .is_err()
                {
                    return Err(SourceError::CallBudget {
                        limit: self.calls_per_request,
                    });
                }
                let fetched = upstream.fetch_buildings(&t.bounds()).await;
                self.metrics
                    .upstream
                    .get_or_create(&upstream_result(fetched.as_ref().err()))
                    .inc();
                let body = fetched?;
                self.store.put(&t, &body, DataOrigin::Overpass).await?;
                // No subscriber (yet) is not an error.
                let _ = self.changes.send(DataChanged {
                    area: affected_area(&t),
                    first_fetch: true,
                });
                parse(body.into(), Some(self.store.clock().now_secs())).await
            })
            .await
            .map_err(|e: Arc<SourceError>| (*e).clone());
        if !loaded.load(Ordering::Relaxed) {
            self.metrics.cache("osm_memory", true);
        } else if self.version.load(Ordering::SeqCst) != version {
            self.parsed.invalidate(&t).await;
        }
        // Stale data is served now and refreshed in the background.
        if let Ok(p) = &result
            && p.fetched_at
                .is_some_and(|f| self.store.clock().now_secs() - f > self.ttl_secs)
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
        let (store, metrics, changes) = (
            self.store.clone(),
            self.metrics.clone(),
            self.changes.clone(),
        );
        let (parsed, sets, version) =
            (self.parsed.clone(), self.sets.clone(), self.version.clone());
        // The mark is cleared when the task ends, whatever happens.
        let done = RefreshDone(self.refreshing.clone(), t);
        tokio::spawn(async move {
            let fetched = upstream.fetch_buildings(&t.bounds()).await;
            metrics
                .upstream
                .get_or_create(&upstream_result(fetched.as_ref().err()))
                .inc();
            match fetched {
                Ok(body) => match store.put(&t, &body, DataOrigin::Overpass).await {
                    Ok(changed) if !changed => {
                        // Read back with its new fetch time, so it is not stale any more.
                        version.fetch_add(1, Ordering::SeqCst);
                        parsed.invalidate(&t).await;
                        tracing::debug!(tile = ?t, "OSM data refreshed, unchanged");
                    }
                    Ok(_) => {
                        version.fetch_add(1, Ordering::SeqCst);
                        parsed.invalidate(&t).await;
                        let _ = sets.invalidate_entries_if(move |k, _| k.contains(&t));
                        tracing::info!(tile = ?t, "OSM data changed");
                        // No subscriber (yet) is not an error.
                        let _ = changes.send(DataChanged {
                            area: affected_area(&t),
                            first_fetch: false,
                        });
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
) -> Result<Arc<ParsedDataTile>, SourceError> {
    tokio::task::spawn_blocking(move || {
        read_buildings(&body)
            .map(|b| {
                Arc::new(ParsedDataTile {
                    records: b.buildings.into_iter().map(Arc::new).collect(),
                    skipped: b.skipped,
                    repaired: b.repaired,
                    present: true,
                    fetched_at,
                })
            })
            .map_err(|e| SourceError::Unreadable(e.to_string()))
    })
    .await?
}

impl BuildingSource for DataTileSource {
    fn buildings<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<AreaBuildings, SourceError>> {
        Box::pin(self.area(bbox, true))
    }

    fn held_area<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<AreaBuildings, SourceError>> {
        Box::pin(self.area(bbox, false))
    }

    fn subscribe(&self) -> broadcast::Receiver<DataChanged> {
        self.changes.subscribe()
    }

    fn changed_elsewhere(&self, area: Option<&GeoBbox>) {
        // What is being parsed or assembled now may hold the old data: answered, not kept.
        self.version.fetch_add(1, Ordering::SeqCst);
        let Some(area) = area.copied() else {
            self.parsed.invalidate_all();
            self.sets.invalidate_all();
            return;
        };
        let touched = move |t: &TileCoord| t.bounds().intersects(&area);
        let dropped = self
            .parsed
            .invalidate_entries_if(move |t, _| touched(t))
            .and_then(|_| {
                self.sets
                    .invalidate_entries_if(move |ts, _| ts.iter().any(touched))
            });
        if let Err(e) = dropped {
            // Cannot select entries: drop them all rather than keep old data.
            tracing::error!("cannot drop changed data tiles selectively ({e}); dropping all");
            self.parsed.invalidate_all();
            self.sets.invalidate_all();
        }
    }

    fn changed_here(&self, area: &GeoBbox) {
        self.changed_elsewhere(Some(area));
        // No subscriber is an error to ignore: nothing was generated yet.
        let _ = self.changes.send(DataChanged {
            area: *area,
            first_fetch: false,
        });
    }

    fn fingerprint(&self) -> &str {
        "tiles"
    }

    fn summary(&self) -> usize {
        self.parsed.entry_count() as usize
    }

    fn memory_use<'a>(&'a self) -> BoxFuture<'a, Vec<(&'static str, u64)>> {
        Box::pin(async move {
            self.parsed.run_pending_tasks().await;
            self.sets.run_pending_tasks().await;
            vec![
                ("osm_tiles", self.parsed.weighted_size()),
                ("building_sets", self.sets.weighted_size()),
            ]
        })
    }

    fn extent(&self) -> Option<GeoBbox> {
        None
    }

    fn held_buildings<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<Arc<BuildingSet>, SourceError>> {
        Box::pin(async move {
            let mut seen = HashSet::new();
            let mut records = Vec::new();
            for t in data_tiles_for(bbox) {
                if let Some(stored) = self.store.get(&t).await? {
                    let parsed = parse(stored.body, None).await?;
                    records.extend(parsed.records.iter().filter(|r| seen.insert(r.id)).cloned());
                }
            }
            let set =
                tokio::task::spawn_blocking(move || BuildingSet::from_shared(records)).await?;
            Ok(Arc::new(set))
        })
    }

    fn data_tiles<'a>(&'a self) -> BoxFuture<'a, Result<Vec<TileCoord>, SourceError>> {
        Box::pin(async move { Ok(self.store.stored_tiles().await?) })
    }

    fn prior_scope(&self, lon: f64, lat: f64) -> PriorScope {
        PriorScope::DataTile(TileCoord::containing(data_tile::DATA_ZOOM, lon, lat))
    }

    fn prior_records<'a>(
        &'a self,
        scope: PriorScope,
    ) -> BoxFuture<'a, Result<Vec<Arc<BuildingRecord>>, SourceError>> {
        Box::pin(async move {
            let PriorScope::DataTile(t) = scope else {
                return Err(SourceError::Unreadable(
                    "data tiles have no prior over everything".to_owned(),
                ));
            };
            let budget = AtomicUsize::new(self.calls_per_request);
            Ok(self.data_tile(t, &budget).await?.records.clone())
        })
    }
}

//! The world tileset's tile summaries (`citymesh_core::tiles3d::TileSummary`): one per data tile
//! that holds buildings and one per coarser tile above them, each made from its four children,
//! so a tileset file, and a coarse content tile, reads a bounded number of summaries and never
//! the data tiles under it.
//!
//! They are made in the background when the server starts (data tiles first, then each zoom up
//! to the root) and again over an area whose data changed; `/health` says how far it got. A data
//! tile's summary is kept in the tile store (`store/summaries.rs`), so a restart reads it
//! instead of reading the data tile's buildings again; the coarser ones are made from them
//! (cheap: four children each). A
//! tileset file asked before its summaries exist answers 503 with `Retry-After`, not a tree
//! with holes.

use super::TileCache;
use crate::pipeline::Generator;
use crate::source::SourceError;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::tiles3d::{
    BLOCK_ZOOM, DATA_ZOOM, TileSummary, WorldTile, children_of, summary_tile,
};
use futures_util::StreamExt;
use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};

/// Summaries made at once (each on the blocking pool).
const CONCURRENCY: usize = 2;

/// How far making the summaries got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, utoipa::ToSchema)]
pub struct SummaryProgress {
    /// Data tiles summarised so far, of `data_tiles`.
    pub done: usize,
    pub data_tiles: usize,
    /// Of `done`, the summaries read from the store (kept from an earlier start) rather than
    /// made from the data tile's buildings.
    pub kept: usize,
    /// Every summary up to the root is made.
    pub ready: bool,
    /// Summaries held (data tiles and the tiles above them).
    pub held: usize,
}

/// The summaries of every tile of the world tree that holds buildings.
pub struct Summaries {
    tiles: RwLock<HashMap<TileCoord, Arc<TileSummary>>>,
    /// The area the tree covers beyond the data held (`--world-area`: its leaves fetch).
    area: Option<GeoBbox>,
    done: AtomicUsize,
    kept: AtomicUsize,
    data_tiles: AtomicUsize,
    /// Every summary is made (watched by [`Summaries::ready`]).
    ready: tokio::sync::watch::Sender<bool>,
    /// Counts the makings finished (watched by [`Summaries::summarised`]).
    made: tokio::sync::watch::Sender<u64>,
}

impl Summaries {
    /// Summaries of a tree over the data held and `area` (tiles there without data are
    /// unfetched: `WorldTile::unfetched`).
    pub fn new(area: Option<GeoBbox>) -> Arc<Self> {
        Arc::new(Self {
            tiles: RwLock::default(),
            area,
            done: AtomicUsize::new(0),
            kept: AtomicUsize::new(0),
            data_tiles: AtomicUsize::new(0),
            ready: tokio::sync::watch::channel(false).0,
            made: tokio::sync::watch::channel(0).0,
        })
    }

    /// Waits until every summary is made.
    pub async fn ready(&self) {
        let mut ready = self.ready.subscribe();
        // The sender lives as long as `self`: the wait ends only when it is ready.
        let _ = ready.wait_for(|r| *r).await;
    }

    /// Waits until tile `t` has a summary (its data was summarised).
    pub async fn summarised(&self, t: &TileCoord) {
        let mut made = self.made.subscribe();
        // The sender lives as long as `self`: the wait ends only when the tile is summarised.
        let _ = made.wait_for(|_| self.get(t).is_some()).await;
    }

    pub fn progress(&self) -> SummaryProgress {
        SummaryProgress {
            done: self.done.load(Ordering::Relaxed),
            data_tiles: self.data_tiles.load(Ordering::Relaxed),
            kept: self.kept.load(Ordering::Relaxed),
            ready: self.is_ready(),
            held: self.read().len(),
        }
    }

    pub fn is_ready(&self) -> bool {
        *self.ready.borrow()
    }

    fn read(&self) -> std::sync::RwLockReadGuard<'_, HashMap<TileCoord, Arc<TileSummary>>> {
        self.tiles
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn write(&self) -> std::sync::RwLockWriteGuard<'_, HashMap<TileCoord, Arc<TileSummary>>> {
        self.tiles
            .write()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The summary of a tile at or above the data tiles.
    pub fn get(&self, t: &TileCoord) -> Option<Arc<TileSummary>> {
        self.read().get(t).cloned()
    }

    /// The area covered beyond the data held (`--world-area`).
    pub fn area(&self) -> Option<&GeoBbox> {
        self.area.as_ref()
    }

    /// The tile as the world tileset lists it, if it exists: at or above the data tiles when
    /// its summary exists, below them when its data tile's does; in the covered area
    /// (`--world-area`) every tile exists, unfetched where no data is held under it.
    pub fn world_tile(&self, t: TileCoord) -> Option<WorldTile> {
        let held = self.get(&summary_tile(t)).map(|s| WorldTile::of(t, &s));
        let covered = self.area.filter(|a| t.bounds().overlaps(a));
        match (held, covered) {
            // A data tile held is fetched whole: no tile below it is unfetched.
            (Some(tile), Some(area)) if t.z < DATA_ZOOM => Some(tile.covering_unfetched(t, &area)),
            (Some(tile), _) => Some(tile),
            (None, area) => area.map(|a| WorldTile::unfetched(t, &a)),
        }
    }

    /// Makes every summary: those of the source's data tiles (with `reuse`, read from `store`
    /// where it kept one for this data version), then each zoom up to the root; what it makes
    /// is kept in `store`.
    pub async fn make_all(
        &self,
        generator: &Generator,
        store: &TileCache,
        reuse: bool,
    ) -> Result<(), SourceError> {
        self.ready.send_replace(false);
        let tiles = generator.source.data_tiles().await?;
        self.data_tiles.store(tiles.len(), Ordering::Relaxed);
        self.done.store(0, Ordering::Relaxed);
        self.kept.store(0, Ordering::Relaxed);
        self.remake(generator, tiles, Vec::new(), store, reuse)
            .await?;
        self.ready.send_replace(true);
        Ok(())
    }

    /// Makes again the summaries of the data tiles over `area` (data changed there), and the
    /// summaries above them; the new ones are kept in `store` (the old rows were made from the
    /// old data, and are never read).
    pub async fn remake_over(
        &self,
        generator: &Generator,
        area: &GeoBbox,
        store: &TileCache,
    ) -> Result<(), SourceError> {
        let listed = generator.source.data_tiles().await?;
        let known: Vec<TileCoord> = self
            .read()
            .keys()
            .filter(|t| t.z == DATA_ZOOM)
            .copied()
            .collect();
        let over = |t: &TileCoord| t.bounds().intersects(area);
        let changed: Vec<TileCoord> = listed.iter().filter(|t| over(t)).copied().collect();
        let gone: Vec<TileCoord> = known
            .into_iter()
            .filter(|t| over(t) && !listed.contains(t))
            .collect();
        self.data_tiles.store(listed.len(), Ordering::Relaxed);
        self.remake(generator, changed, gone, store, false).await
    }

    /// Summarises `tiles` (data tiles; reading the kept ones from `store` when `reuse`),
    /// forgets `gone`, keeps what it made in `store`, and makes again every summary above
    /// either.
    async fn remake(
        &self,
        generator: &Generator,
        tiles: Vec<TileCoord>,
        gone: Vec<TileCoord>,
        store: &TileCache,
        reuse: bool,
    ) -> Result<(), SourceError> {
        let reused = reuse.then_some(store);
        let mut results = futures_util::stream::iter(tiles.iter().copied())
            .map(|t| summarise_data_tile(generator, t, reused))
            .buffer_unordered(CONCURRENCY);
        // What was made (not read back), to keep.
        let mut made: Vec<(TileCoord, Option<Arc<TileSummary>>)> = Vec::new();
        while let Some(result) = results.next().await {
            let (t, summary, kept) = result?;
            let summary = summary.map(Arc::new);
            {
                let mut held = self.write();
                match &summary {
                    Some(s) => held.insert(t, s.clone()),
                    None => held.remove(&t),
                };
            }
            if kept {
                self.kept.fetch_add(1, Ordering::Relaxed);
            } else {
                made.push((t, summary));
            }
            self.done.fetch_add(1, Ordering::Relaxed);
            if made.len() >= KEEP_BATCH {
                keep(store, &mut made).await;
            }
        }
        drop(results);
        keep(store, &mut made).await;
        {
            let mut held = self.write();
            for t in &gone {
                held.remove(t);
            }
        }
        let mut level: BTreeSet<TileCoord> = tiles.into_iter().chain(gone).collect();
        for z in (0..DATA_ZOOM).rev() {
            level = level
                .iter()
                .map(|t| TileCoord {
                    z,
                    x: t.x >> 1,
                    y: t.y >> 1,
                })
                .collect();
            for parent in &level {
                let children: Vec<Arc<TileSummary>> = {
                    let held = self.read();
                    children_of(parent)
                        .iter()
                        .filter_map(|c| held.get(c).cloned())
                        .collect()
                };
                let summary = summarise_parent(generator, *parent, children).await?;
                let mut held = self.write();
                match summary {
                    Some(s) => held.insert(*parent, Arc::new(s)),
                    None => held.remove(parent),
                };
            }
        }
        self.made.send_modify(|n| *n += 1);
        Ok(())
    }
}

/// Data tile summaries written to the store at once.
const KEEP_BATCH: usize = 64;

/// Keeps `made` in `store` and empties it. A failure costs only the time to make them again at
/// the next start.
async fn keep(store: &TileCache, made: &mut Vec<(TileCoord, Option<Arc<TileSummary>>)>) {
    if !made.is_empty() {
        let rows: Vec<(TileCoord, Option<&TileSummary>)> =
            made.iter().map(|(t, s)| (*t, s.as_deref())).collect();
        if let Err(e) = store.put_summaries(&rows).await {
            tracing::warn!(summaries = rows.len(), "cannot keep tile summaries: {e}");
        }
    }
    made.clear();
}

/// The summary of one data tile: the one `kept` holds for this data version, else made from
/// the source's buildings around it and the DEM. Says whether it was read from `kept`.
pub(crate) async fn summarise_data_tile(
    generator: &Generator,
    t: TileCoord,
    kept: Option<&TileCache>,
) -> Result<(TileCoord, Option<TileSummary>, bool), SourceError> {
    if let Some(store) = kept {
        match store.kept_summary(t).await {
            Ok(Some(s)) => return Ok((t, Some(s), true)),
            Ok(None) => {}
            Err(e) => tracing::warn!(tile = ?t, "cannot read a kept summary ({e}); made again"),
        }
    }
    let set = generator.source.held_buildings(&t.bounds()).await?;
    let dem = generator.dem.clone();
    let roof_method = generator.roof_method;
    let summary = tokio::task::spawn_blocking(move || {
        let groups = set.clusters_of_tile(&t);
        let extent = citymesh_core::building::set::extent_with(&t.bounds(), &groups);
        let model = dem.lookup(&extent.grown_by_degrees(0.001)).model;
        TileSummary::of_data_tile(t, &set, &model, roof_method)
    })
    .await?;
    Ok((t, summary, false))
}

/// The summary of a tile above the data tiles, from its children's (and the DEM under it when
/// it draws blocks).
pub(crate) async fn summarise_parent(
    generator: &Generator,
    t: TileCoord,
    children: Vec<Arc<TileSummary>>,
) -> Result<Option<TileSummary>, SourceError> {
    if children.is_empty() {
        return Ok(None);
    }
    let dem = generator.dem.clone();
    Ok(tokio::task::spawn_blocking(move || {
        let refs: Vec<&TileSummary> = children.iter().map(AsRef::as_ref).collect();
        if t.z >= BLOCK_ZOOM {
            let model = dem.lookup(&t.bounds()).model;
            TileSummary::of_children(t, &refs, Some(&model))
        } else {
            TileSummary::of_children(t, &refs, None)
        }
    })
    .await?)
}

/// Makes the summaries in the background, then makes them again over every area whose data
/// changed, and drops the world tiles generated from the old ones (the tile cache's own
/// invalidation may have run before the summaries changed). Stops with the server.
pub fn keep_summaries(
    generator: Generator,
    summaries: Arc<Summaries>,
    tiles: Arc<super::TileCache>,
) {
    let mut changes = generator.source.subscribe();
    tokio::spawn(async move {
        let work = async {
            let started = std::time::Instant::now();
            match summaries.make_all(&generator, &tiles, true).await {
                Ok(()) => {
                    let p = summaries.progress();
                    tracing::info!(
                        data_tiles = p.data_tiles,
                        kept = p.kept,
                        held = p.held,
                        ms = started.elapsed().as_millis() as u64,
                        "world tileset summaries made"
                    );
                }
                Err(e) => tracing::error!("cannot make the world tileset's summaries: {e}"),
            }
            loop {
                match changes.recv().await {
                    Ok(crate::source::DataChanged { area, first_fetch }) => {
                        if let Err(e) = summaries.remake_over(&generator, &area, &tiles).await {
                            tracing::error!(%area, "cannot remake summaries: {e}");
                        }
                        // Data fetched for the first time changes only the world content over
                        // a covered area (its blocks were made without it); elsewhere nothing
                        // was made from it.
                        let stale =
                            !first_fetch || summaries.area().is_some_and(|a| a.intersects(&area));
                        if stale && let Err(e) = tiles.invalidate_area(&area).await {
                            tracing::error!(%area, "cannot invalidate tiles: {e}");
                        }
                    }
                    Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {
                        // Changes were missed: the kept summaries may be of old data too.
                        if let Err(e) = summaries.make_all(&generator, &tiles, false).await {
                            tracing::error!("cannot remake summaries: {e}");
                        }
                        tiles.invalidate_memory();
                    }
                    Err(tokio::sync::broadcast::error::RecvError::Closed) => break,
                }
            }
        };
        tokio::select! {
            () = generator.stopping.cancelled() => {}
            () = work => {}
        }
    });
}

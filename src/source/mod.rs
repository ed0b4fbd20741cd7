//! Where buildings come from. Every source implements [`BuildingSource`]: it answers the
//! buildings an area needs and announces the areas whose data changed, so one subscriber (the
//! tile cache's invalidation, `crate::cache::invalidation`) drops what was built from old data.
//! Sources know nothing of HTTP or of the caches of generated tiles; they fail with their own
//! [`SourceError`], which only `crate::error` maps to a status.
//!
//! Two sources exist: the `--osm` files (or the procedural demo city) held in memory
//! ([`FileSource`]), and OSM data tiles in SQLite filled from Overpass or by `citymesh import`
//! ([`DataTileSource`]). A PostgreSQL-backed source would be a third implementation of the trait,
//! chosen in `crate::server`; nothing in `crate::routes` or `crate::pipeline` would change.

pub mod data_tiles;
mod error;
mod files;

pub use data_tiles::DataTileSource;
pub use error::SourceError;
pub use files::{FileSource, OsmFileError, load_osm_files, read_osm_file};

use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, Repaired, Skipped};
use futures_util::future::BoxFuture;
use std::sync::Arc;
use tokio::sync::broadcast;

/// The buildings of an area and where they came from.
#[derive(Debug, Clone)]
pub struct AreaBuildings {
    pub set: Arc<BuildingSet>,
    /// `files`, `stored`, `request` (given by the client), or
    /// `missing=14/x/y,... (offline: no buildings there)`.
    pub origin: String,
    /// Buildings the data has near the area that could not be built when it was read.
    pub load_skips: Vec<Skipped>,
    /// Buildings built with less than the data describes (reported when generated).
    pub repaired: Arc<Vec<Repaired>>,
}

impl AreaBuildings {
    /// Buildings given with the request: nothing was skipped reading them here.
    pub fn given(set: Arc<BuildingSet>) -> Self {
        Self {
            set,
            origin: "request".to_owned(),
            load_skips: Vec::new(),
            repaired: Arc::default(),
        }
    }
}

/// The skips whose known place touches `bbox` (those the data cannot place are kept too: they
/// came from the data that covers the area).
pub fn skips_near(skips: &[Skipped], bbox: &GeoBbox) -> Vec<Skipped> {
    skips
        .iter()
        .filter(|s| {
            s.bounds.is_none_or(|[w, so, e, n]| {
                w <= bbox.max_lon()
                    && e >= bbox.min_lon()
                    && so <= bbox.max_lat()
                    && n >= bbox.min_lat()
            })
        })
        .copied()
        .collect()
}

/// The data of an area changed: everything built from it is stale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DataChanged {
    /// The area whose served content may have used the changed data (margin included).
    pub area: GeoBbox,
    /// The data was fetched for the first time: nothing was generated from it, and every
    /// request over it waited for it, so only what is made from held data alone (the world
    /// tileset's summaries, and its content in a `--world-area`) changes.
    pub first_fetch: bool,
}

/// The area whose tagged buildings teach the roof prior of a building (docs/method.md section
/// 14): all of the source's buildings (files), or those of the data tile holding the building's
/// representative point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PriorScope {
    Everything,
    DataTile(TileCoord),
}

impl PriorScope {
    /// `all`, or the data tile as `z/x/y`.
    pub fn name(&self) -> String {
        match self {
            PriorScope::Everything => "all".to_owned(),
            PriorScope::DataTile(t) => format!("{}/{}/{}", t.z, t.x, t.y),
        }
    }

    /// Whether data changed over `area` changes this scope's buildings.
    pub fn touches(&self, area: &GeoBbox) -> bool {
        match self {
            PriorScope::Everything => true,
            PriorScope::DataTile(t) => t.bounds().intersects(area),
        }
    }
}

/// A source of buildings.
pub trait BuildingSource: Send + Sync {
    /// The buildings an area needs: at least every building group that touches `bbox`, whole.
    fn buildings<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<AreaBuildings, SourceError>>;

    /// [`BuildingSource::buildings`] from what the source holds alone, through its caches:
    /// never asks upstream (a data tile it does not hold has no buildings). The world tileset's
    /// content is made with it: the tree covers what is held, so a tile at its edge never
    /// waits on (or fails with) an upstream for the data tiles beside it. Sources that never
    /// ask upstream answer as `buildings`.
    fn held_area<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<AreaBuildings, SourceError>> {
        self.buildings(bbox)
    }

    /// Announcements of changed areas, from now on.
    fn subscribe(&self) -> broadcast::Receiver<DataChanged>;

    /// Another process changed the data over `area` (`None`: anywhere), in the database this
    /// source reads (a replica on the same PostgreSQL, or `citymesh import`): drop what is held
    /// of it in memory. Sources that read nothing shared hold nothing to drop.
    fn changed_elsewhere(&self, _area: Option<&GeoBbox>) {}

    /// This process changed the stored data over `area` (a replication diff applied by the
    /// server): drop what is held of it and announce it to the subscribers, as a refresh does.
    fn changed_here(&self, _area: &GeoBbox) {}

    /// Part of every generated tile's cache key: changes when the source's data changes in a way
    /// it does not announce (files edited between runs).
    fn fingerprint(&self) -> &str;

    /// Buildings held (files) or data tiles parsed (data tiles), for `/health`.
    fn summary(&self) -> usize;

    /// The extent of all buildings when the source knows it up front (files), else `None`.
    fn extent(&self) -> Option<GeoBbox>;

    /// The buildings an area needs, as [`BuildingSource::buildings`], from what the source
    /// holds alone: never asks upstream, starts no refresh and leaves the request caches alone
    /// (the world tileset's summaries read every data tile with it).
    fn held_buildings<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<Arc<BuildingSet>, SourceError>>;

    /// The data tiles (`data_tiles::data_tile::DATA_ZOOM`) that hold buildings: the stored
    /// ones, or those holding the files' groups. The world tileset is summarised over them.
    fn data_tiles<'a>(&'a self) -> BoxFuture<'a, Result<Vec<TileCoord>, SourceError>>;

    /// Which area's tags teach the roof prior of a building whose outline's first node is at
    /// (`lon`, `lat`).
    fn prior_scope(&self, lon: f64, lat: f64) -> PriorScope;

    /// The buildings of a prior's area (which may ask upstream, within one request's budget).
    fn prior_records<'a>(
        &'a self,
        scope: PriorScope,
    ) -> BoxFuture<'a, Result<Vec<Arc<BuildingRecord>>, SourceError>>;

    /// Bytes its memory caches weigh now, by cache (none for files, held whole).
    fn memory_use<'a>(&'a self) -> BoxFuture<'a, Vec<(&'static str, u64)>> {
        Box::pin(async { Vec::new() })
    }
}

/// Capacity of a source's change announcements; a subscriber that falls further behind drops
/// everything it cached (see `crate::cache::invalidation`).
pub const CHANGE_CAPACITY: usize = 256;

/// At most eight names, then how many more: lists that end up in response headers stay short.
pub fn short_list(names: &[String]) -> String {
    const LISTED: usize = 8;
    if names.len() <= LISTED {
        return names.join(",");
    }
    format!(
        "{},... ({} more)",
        names[..LISTED].join(","),
        names.len() - LISTED
    )
}

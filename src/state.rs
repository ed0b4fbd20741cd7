//! Shared server state: the DEM store, the building source, the tile cache, the metrics and the
//! limits, cheap to clone per request (one reference count: axum clones the state for every
//! request, and many counts bumped from every core cost more than the rest of a cached tile).

use crate::cache::TileCache;
use std::sync::Arc;
use std::time::Duration;

/// Limits that protect the server from requests it should refuse.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub max_bbox_km2: f64,
    /// Most ground cells (1 arc-second) a requested box may span.
    pub max_ground_cells: u64,
    /// Most outline nodes one generation may draw (`--max-scene-nodes`).
    pub max_scene_nodes: usize,
    pub min_zoom: u8,
    pub max_zoom: u8,
    /// How long a request waits for a free generation slot before a 503.
    pub generation_wait: Duration,
    /// How long gathering data and generating may take before a 503.
    pub request_timeout: Duration,
    /// How long a client may take to send a request body before a 408.
    pub body_timeout: Duration,
}

/// The state handlers see: a shared [`ServerState`].
#[derive(Clone)]
pub struct AppState(Arc<ServerState>);

impl AppState {
    pub fn new(state: ServerState) -> Self {
        Self(Arc::new(state))
    }
}

impl std::ops::Deref for AppState {
    type Target = ServerState;

    fn deref(&self) -> &ServerState {
        &self.0
    }
}

/// Everything the server shares between requests.
pub struct ServerState {
    /// Where data tiles, generated tiles, jobs and predictions are kept.
    pub database: crate::db::Database,
    pub tiles: Arc<TileCache>,
    /// The world tileset's tile summaries (made in the background).
    pub summaries: Arc<crate::cache::Summaries>,
    /// Generation and what it needs: source, DEM, slots, limits, metrics, roof settings,
    /// predictions and priors (also what the other handlers read those from).
    pub generator: crate::pipeline::Generator,
    /// Largest upload accepted, bytes.
    pub max_upload_bytes: usize,
    /// Most features and positions an uploaded GeoJSON may have.
    pub geojson_limits: citymesh_core::geojson::GeoJsonLimits,
    /// No data is configured: the buildings are the procedural demo city.
    pub demo: bool,
    /// Where the pages' npm packages are (`node_modules`), served under `/vendor/`.
    pub assets_dir: std::path::PathBuf,
    /// The roof-shape classifier, when `--roof-classifier` loaded it.
    pub classifier: Option<Arc<dyn crate::roofs::classifier::RoofClassifier>>,
    /// Origins whose pages may change state (`--cors-origin`), besides the server's own.
    pub cors_origins: Arc<Vec<String>>,
    /// What the memory caches may hold (`--memory-mb`).
    pub memory_budget: crate::cache::MemoryBudget,
}

impl ServerState {
    /// Bytes each memory cache weighs now, by cache name.
    pub async fn memory_use(&self) -> Vec<(&'static str, u64)> {
        let mut out: Vec<(&'static str, u64)> = self.tiles.memory_use().await.to_vec();
        let dem = self.generator.dem.clone();
        out.push((
            "dem",
            tokio::task::spawn_blocking(move || dem.memory_use())
                .await
                .unwrap_or(0),
        ));
        out.extend(self.generator.source.memory_use().await);
        out.push(("roof_priors", self.generator.priors.weighted_size().await));
        out
    }
}

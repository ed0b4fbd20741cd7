//! Shared server state: the DEM store, the OSM buildings, the tile cache and the limits, cheap to clone per request.

use crate::db::TileStore;
use crate::dem::DemStore;
use crate::osm::OsmData;
use std::sync::Arc;

/// Limits that protect the server from requests it should refuse.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub max_bbox_km2: f64,
    pub min_zoom: u8,
    pub max_zoom: u8,
}

#[derive(Clone)]
pub struct AppState {
    pub dem: Arc<DemStore>,
    pub osm: Arc<OsmData>,
    pub tiles: TileStore,
    pub limits: Limits,
}

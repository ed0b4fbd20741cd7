//! The one place that turns data changes into cache invalidation: it subscribes to the building
//! source's announcements and drops the generated content over each changed area, in memory and
//! in SQLite. `citymesh import` (no server running) drops stored tiles the same way.

use super::store::TileStore;
use super::{RoofPriors, TileCache};
use crate::source::{BuildingSource, DataChanged};
use citymesh_core::geo::GeoBbox;
use std::sync::Arc;
use tokio::sync::broadcast::error::RecvError;

/// Follows `source`'s announcements for as long as the source lives.
pub fn subscribe(source: &dyn BuildingSource, tiles: Arc<TileCache>, priors: Arc<RoofPriors>) {
    let mut changes = source.subscribe();
    tokio::spawn(async move {
        loop {
            match changes.recv().await {
                // Nothing generated used data fetched for the first time.
                Ok(DataChanged {
                    first_fetch: true, ..
                }) => {}
                Ok(DataChanged { area, .. }) => {
                    priors.invalidate_area(&area);
                    match tiles.invalidate_area(&area).await {
                        Ok(n) => {
                            tracing::info!(%area, removed = n, "data changed; tiles invalidated");
                        }
                        Err(e) => tracing::error!(%area, "cannot invalidate tiles: {e}"),
                    }
                }
                Err(RecvError::Lagged(missed)) => {
                    // Which areas changed is lost: nothing in memory can be trusted. Stored
                    // tiles over the missed areas may survive until their data changes again.
                    tracing::warn!(
                        missed,
                        "missed data-change announcements; memory cache dropped"
                    );
                    tiles.invalidate_memory();
                    priors.invalidate_all();
                }
                Err(RecvError::Closed) => break,
            }
        }
    });
}

/// Deletes the stored tiles over each changed area (no server running); answers how many.
pub async fn drop_stored(store: &TileStore, areas: &[GeoBbox]) -> Result<u64, sqlx::Error> {
    let mut removed = 0;
    for area in areas {
        removed += store.delete_overlapping(area).await?;
    }
    Ok(removed)
}

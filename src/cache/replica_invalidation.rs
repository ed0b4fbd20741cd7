//! Invalidation across replicas sharing one PostgreSQL: a data change deletes the stored tiles
//! over its area and announces the area in the same transaction (`store/mod.rs:TileStore::delete_overlapping`); every
//! other replica hears it here and drops what it holds of the area in memory (parsed data,
//! building sets, priors, tiles, scenes). While the listener is disconnected announcements are
//! lost, so each (re)connection drops every memory cache.

use super::store::{DATA_CHANGED_CHANNEL, DataChangedNote};
use super::{RoofPriors, TileCache};
use crate::metrics::Metrics;
use crate::source::BuildingSource;
use citymesh_core::geo::GeoBbox;
use sqlx::PgPool;
use sqlx::postgres::PgListener;
use std::sync::Arc;
use std::time::Duration;

/// What a replica drops when another announces a change.
#[derive(Clone)]
pub struct ReplicaCaches {
    pub source: Arc<dyn BuildingSource>,
    pub tiles: Arc<TileCache>,
    pub priors: Arc<RoofPriors>,
    pub metrics: Arc<Metrics>,
}

impl ReplicaCaches {
    /// Drops what is held of `area` (`None`: everything).
    fn forget(&self, area: Option<&GeoBbox>) {
        self.source.changed_elsewhere(area);
        match area {
            Some(area) => {
                self.priors.invalidate_area(area);
                self.tiles.invalidate_memory_area(area);
            }
            None => {
                self.priors.invalidate_all();
                self.tiles.invalidate_memory();
            }
        }
    }

    fn heard(&self, payload: &str, replica: &str) {
        match DataChangedNote::parse(payload) {
            // This replica acted on its own change before announcing it.
            Some(note) if note.sender == replica => {}
            Some(note) => {
                self.metrics.replicas.data_change_notifications.inc();
                tracing::info!(area = %note.area, from = %note.sender, "data changed on another replica");
                self.forget(Some(&note.area));
            }
            None => {
                tracing::warn!(
                    payload,
                    "unreadable data-change announcement; memory dropped"
                );
                self.forget(None);
            }
        }
    }
}

/// Listens for other replicas' data changes until the process ends; returns once listening, so
/// nothing announced after start-up is missed.
pub async fn listen(pool: PgPool, replica: String, caches: ReplicaCaches) -> anyhow::Result<()> {
    let mut listener = connect(&pool).await?;
    caches.metrics.replicas.listener_connects.inc();
    tokio::spawn(async move {
        loop {
            match listener.try_recv().await {
                Ok(Some(n)) => caches.heard(n.payload(), &replica),
                Ok(None) => {
                    // The connection was lost (the next call reconnects and listens again):
                    // whatever was announced meanwhile is unknown.
                    tracing::warn!("data-change listener reconnecting; memory caches dropped");
                    caches.metrics.replicas.listener_connects.inc();
                    caches.forget(None);
                }
                Err(e) => {
                    tracing::warn!("data-change listener failed ({e}); retrying in 1 s");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    match connect(&pool).await {
                        Ok(l) => {
                            listener = l;
                            caches.metrics.replicas.listener_connects.inc();
                            caches.forget(None);
                        }
                        Err(e) => tracing::warn!("data-change listener not connected: {e}"),
                    }
                }
            }
        }
    });
    Ok(())
}

async fn connect(pool: &PgPool) -> anyhow::Result<PgListener> {
    let mut listener = PgListener::connect_with(pool).await?;
    listener.listen(DATA_CHANGED_CHANNEL).await?;
    Ok(listener)
}

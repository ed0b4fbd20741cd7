//! Start-up and shutdown: logging, the database, the DEM store, the building source, the caches,
//! the listener ([`connections`]: limits on connections and their timeouts), and a graceful stop
//! on SIGINT or SIGTERM.

pub(crate) mod connections;
mod generation;
mod parse_errors;
mod streams;

pub use connections::ConnectionLimits;
pub use generation::{OpenedGenerator, open_generator};
pub use streams::ClientAddr;

use crate::cache::{TileCache, TileStore, invalidation, replica_invalidation};
use crate::cli::ServeArgs;
use crate::clock::Clock;
use crate::db;
use crate::state::{AppState, ServerState};
use std::sync::Arc;
use std::time::Duration;

/// Builds the state a server with these options runs on.
pub async fn build_state(args: &ServeArgs) -> anyhow::Result<AppState> {
    build_state_with_clock(args, Clock::system()).await
}

/// [`build_state`] with the stores' rows stamped by `clock` (tests move a manual clock instead of
/// sleeping past a timestamp).
pub async fn build_state_with_clock(args: &ServeArgs, clock: Clock) -> anyhow::Result<AppState> {
    // Who this process is in the announcements it sends other replicas.
    let replica = crate::roofs::jobs::random_token()?;
    let OpenedGenerator {
        generator,
        database,
        memory,
        classifier,
        demo,
        data_version,
    } = open_generator(args, clock, &replica).await?;
    let metrics = generator.metrics.clone();
    let store = TileStore::open(
        &database,
        args.tile_store_mb.saturating_mul(1 << 20),
        &replica,
    )
    .await?;
    let tiles = Arc::new(
        TileCache::new(store, memory.tiles, data_version, metrics.clone())
            .with_lock_wait(Duration::from_millis(args.generation_lock_wait_ms)),
    );
    invalidation::subscribe(
        generator.source.as_ref(),
        tiles.clone(),
        generator.priors.clone(),
    );
    let summaries = crate::cache::Summaries::new(generator.world_area);
    crate::cache::keep_summaries(generator.clone(), summaries.clone(), tiles.clone());
    if let db::Database::Postgres(pool) = &database {
        let caches = replica_invalidation::ReplicaCaches {
            source: generator.source.clone(),
            tiles: tiles.clone(),
            priors: generator.priors.clone(),
            metrics,
        };
        replica_invalidation::listen(pool.clone(), replica.clone(), caches).await?;
        crate::roofs::jobs::replica_predictions::listen(pool.clone(), generator.roofs.clone())
            .await?;
        tracing::info!(replica = %replica, "sharing PostgreSQL with other replicas");
    }
    Ok(AppState::new(ServerState {
        database,
        classifier,
        generator,
        cors_origins: Arc::new(args.cors_origin.clone()),
        memory_budget: memory,
        tiles,
        summaries,
        max_upload_bytes: args.max_upload_mb.saturating_mul(1 << 20) as usize,
        geojson_limits: citymesh_core::geojson::GeoJsonLimits {
            max_features: args.max_features,
            max_vertices: args.max_vertices,
        },
        demo,
        assets_dir: args.assets_dir.clone(),
    }))
}

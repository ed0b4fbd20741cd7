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
    if let Some(url) = &args.replicate_url {
        follow_feed(args, url, &database, &generator, &replica).await?;
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

/// Follows a replication feed in the background (`--replicate-url`): each diff applied drops
/// what it changed from the memory caches through the source's announcements, as a refresh
/// does (the stored tiles went in the diff's own step).
async fn follow_feed(
    args: &ServeArgs,
    url: &str,
    database: &db::Database,
    generator: &crate::pipeline::Generator,
    replica: &str,
) -> anyhow::Result<()> {
    use crate::source::data_tiles::OsmTileStore;
    use crate::source::data_tiles::replication::feed::{Feed, FollowTiming, follow};
    anyhow::ensure!(
        args.osm.is_empty() && generator.source.fingerprint() == "tiles",
        "--replicate-url follows a feed over imported data: serve the database the data was \
         imported into, without --osm"
    );
    let feed = Feed::new(url)?;
    let store = OsmTileStore::new(database.clone());
    let tiles = TileStore::open(database, u64::MAX, replica).await?;
    let timing = FollowTiming {
        interval: Duration::from_secs(args.replicate_interval_s),
        max_backoff: Duration::from_secs(600),
    };
    let (source, metrics) = (generator.source.clone(), generator.metrics.clone());
    let failures = metrics.clone();
    let from = args.replicate_from_sequence;
    let stopping = generator.stopping.clone();
    tokio::spawn(async move {
        let work = follow(
            store,
            tiles,
            feed,
            from,
            timing,
            move |r| {
                metrics.replication.diffs_applied.inc();
                if let Some(s) = r.sequence {
                    metrics.replication.sequence.set(s);
                }
                for area in &r.areas {
                    source.changed_here(area);
                }
                tracing::info!(
                    sequence = r.sequence,
                    buildings = r.buildings_changed,
                    tiles_dropped = r.tiles_dropped,
                    "replication diff applied"
                );
            },
            move |_| {
                failures.replication.errors.inc();
            },
        );
        tokio::select! {
            () = stopping.cancelled() => {}
            () = work => {}
        }
    });
    Ok(())
}

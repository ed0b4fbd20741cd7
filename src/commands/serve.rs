//! `citymesh serve`: the server's state built from the options, the roof workers started, and
//! connections served until SIGINT or SIGTERM, then a clean stop (tiles written, adaptations
//! recorded).

use crate::cli::ServeArgs;
use crate::server::build_state;
use crate::server::connections::{self, ConnectionLimits};
use anyhow::Context;
use std::io::IsTerminal;
use std::time::Duration;
use tracing_subscriber::EnvFilter;

/// Runs `citymesh serve` until SIGINT or SIGTERM.
pub async fn run(args: ServeArgs) -> anyhow::Result<()> {
    let filter = EnvFilter::try_new(&args.log_level)
        .with_context(|| format!("--log-level '{}' is not a valid filter", args.log_level))?;
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stdout().is_terminal())
        .init();

    let state = build_state(&args).await?;
    let workers = state.generator.roofs.spawn_workers(
        args.classify_workers,
        crate::roofs::jobs::worker::WorkerConfig {
            lease: Duration::from_secs_f64(args.classify_lease_s.clamp(1.0, 86_400.0)),
            ..Default::default()
        },
    );
    match state.generator.roofs.why_not_running() {
        None => tracing::info!(
            workers = workers.len(),
            "roof classification workers started"
        ),
        Some(why) => tracing::info!("roof jobs are queued but not run here: {why}"),
    }
    if state.generator.dem.file_count() == 0 {
        tracing::warn!(dir = %args.dem_dir.display(), "no SRTM files: the ground is flat at 0 m (pass --dem-dir)");
    }
    let listener = tokio::net::TcpListener::bind(args.listen)
        .await
        .with_context(|| format!("cannot listen on {}", args.listen))?;
    let addr = listener.local_addr()?;
    tracing::info!(
        "citymesh {} listening on http://{addr}/ (API docs at http://{addr}/docs)",
        env!("CARGO_PKG_VERSION")
    );
    if state.demo {
        tracing::info!(
            "no data configured (no --osm, --overpass-url, DEM files or imported data): serving a \
             procedural demo city at {} E {} N; open http://{addr}/ or http://{addr}/procedural.glb",
            citymesh_core::procedural::DEFAULT_LON,
            citymesh_core::procedural::DEFAULT_LAT
        );
    }
    let limits = ConnectionLimits {
        max_connections: args.max_connections.max(1),
        reserved_connections: args.reserved_connections,
        first_byte_timeout: Duration::from_secs_f64(args.first_byte_timeout_s),
        header_timeout: Duration::from_secs_f64(args.header_timeout_s),
        idle_timeout: Duration::from_secs_f64(args.idle_timeout_s),
    };
    let tiles = state.tiles.clone();
    let roofs = state.generator.roofs.clone();
    let stopping = state.generator.stopping.clone();
    let signal = async move {
        shutdown_signal().await;
        // Long work stops now; requests in flight finish.
        stopping.cancel();
    };
    let metrics = state.generator.metrics.clone();
    connections::serve(listener, crate::routes::app(state), limits, metrics, signal).await;
    // Tiles generated last are written to the database after their responses: finish those
    // writes.
    tiles.flush().await;
    roofs.shut_down(Duration::from_secs(10)).await;
    for w in workers {
        w.abort();
    }
    tracing::info!("stopped");
    Ok(())
}

async fn shutdown_signal() {
    let ctrl_c = async {
        if let Err(e) = tokio::signal::ctrl_c().await {
            tracing::error!("cannot listen for Ctrl-C: {e}");
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(e) => {
                tracing::error!("cannot listen for SIGTERM: {e}");
                std::future::pending::<()>().await;
            }
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = terminate => {},
    }
    tracing::info!("shutting down: finishing requests in flight");
}

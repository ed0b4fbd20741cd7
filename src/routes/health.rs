//! `GET /health`: is the server up, does its database answer, and what data does it have.

use crate::error::{AppError, ErrorBody};
use crate::state::AppState;
use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;

#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// Always `ok` (a database that does not answer makes `/health` a 503 error instead).
    #[schema(example = "ok")]
    pub status: &'static str,
    /// The database, which answered.
    pub database: DatabaseHealth,
    /// The citymesh version.
    pub version: &'static str,
    /// Number of SRTM files in the DEM directory.
    pub dem_files: usize,
    /// Buildings and building parts loaded from `--osm` files, or OSM data tiles held in memory.
    pub buildings: usize,
    /// The roof classifier's model id (sha256 of the ONNX file) when it is loaded
    /// (`--roof-classifier`), else null.
    pub roof_classifier: Option<String>,
    /// How far the world tileset's summaries are made (`GET /3dtiles/tileset.json` without a
    /// box answers 503 until `ready`).
    pub world: crate::cache::SummaryProgress,
    /// How fresh the imported data is: the last replication diff applied (`citymesh
    /// replicate`, `serve --replicate-url`), or null when none was.
    pub replication: Option<Freshness>,
}

/// The last replication diff applied to the data.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Freshness {
    /// Its sequence number in the feed.
    pub sequence: i64,
    /// The feed's time of it (ISO 8601, UTC): the data holds OpenStreetMap as it was then.
    #[schema(example = "2026-12-07T10:00:00Z")]
    pub timestamp: String,
    /// The feed it came from.
    pub url: String,
    /// When it was applied, Unix seconds.
    pub applied_at: i64,
    /// Seconds from `timestamp` to now: how far behind OpenStreetMap the data is.
    pub age_s: Option<i64>,
}

/// The data's freshness, read from the database (`None` when no diff was applied, or the
/// database does not answer).
pub async fn freshness(state: &AppState) -> Option<Freshness> {
    let store = crate::source::data_tiles::OsmTileStore::new(state.database.clone());
    let s = store.replication_state().await.ok()??;
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    let age_s = crate::source::data_tiles::replication::feed::unix_seconds(&s.timestamp)
        .map(|t| (now - t).max(0));
    Some(Freshness {
        sequence: s.sequence,
        timestamp: s.timestamp,
        url: s.url,
        applied_at: s.applied_at,
        age_s,
    })
}

/// How the database answered.
#[derive(Debug, Serialize, ToSchema)]
pub struct DatabaseHealth {
    /// `sqlite` (one machine) or `postgres` (shared by replicas).
    #[schema(example = "sqlite")]
    pub backend: &'static str,
    /// How long a trivial query took, milliseconds.
    pub latency_ms: f64,
}

/// How long /health waits for the database.
const DATABASE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// Liveness, the database, and a summary of the configured data.
#[utoipa::path(get, path = "/health", tag = "service",
    responses(
        (status = 200, description = "The server is up and its database answers", body = Health),
        (status = 503, description = "The server is up but its database did not answer within 2 s (`database_unreachable`; tiles cached in memory are still served): a load balancer should send requests elsewhere", body = ErrorBody),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn health(State(state): State<AppState>) -> Result<Json<Health>, AppError> {
    let started = std::time::Instant::now();
    let backend = state.database.backend();
    let failed = match tokio::time::timeout(DATABASE_WAIT, state.database.ping()).await {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(_) => Some(format!("no answer within {} s", DATABASE_WAIT.as_secs())),
    };
    if let Some(why) = failed {
        return Err(AppError::Unavailable {
            code: "database_unreachable",
            detail: format!(
                "the {backend} database does not answer ({why}): check that it runs and that \
                 this replica reaches it; tiles held in memory are still served"
            ),
            retry_after_secs: 5,
        });
    }
    Ok(Json(Health {
        status: "ok",
        database: DatabaseHealth {
            backend,
            latency_ms: started.elapsed().as_secs_f64() * 1e3,
        },
        version: env!("CARGO_PKG_VERSION"),
        dem_files: state.generator.dem.file_count(),
        buildings: state.generator.source.summary(),
        roof_classifier: state.classifier.as_ref().map(|c| c.model_id().to_owned()),
        world: state.summaries.progress(),
        replication: freshness(&state).await,
    }))
}

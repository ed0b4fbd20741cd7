//! `GET /health`: is the server up, does its database answer, and what data does it have.

use crate::error::ErrorBody;
use crate::state::AppState;
use axum::Json;
use axum::extract::State;
use axum::http::StatusCode;
use serde::Serialize;
use utoipa::ToSchema;

#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// `ok`, or `database_unreachable` (with status 503) when the database did not answer.
    #[schema(example = "ok")]
    pub status: &'static str,
    /// The database and whether it answered.
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
}

/// How the database answered.
#[derive(Debug, Serialize, ToSchema)]
pub struct DatabaseHealth {
    /// `sqlite` (one machine) or `postgres` (shared by replicas).
    #[schema(example = "sqlite")]
    pub backend: &'static str,
    /// Whether a trivial query was answered within 2 s.
    pub reachable: bool,
    /// How long it took, milliseconds.
    pub latency_ms: f64,
    /// Why it was not reachable.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// How long /health waits for the database.
const DATABASE_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// Liveness, the database, and a summary of the configured data.
#[utoipa::path(get, path = "/health", tag = "service",
    responses(
        (status = 200, description = "The server is up and its database answers", body = Health),
        (status = 503, description = "The server is up but its database did not answer within 2 s (tiles cached in memory are still served)", body = Health),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn health(State(state): State<AppState>) -> (StatusCode, Json<Health>) {
    let started = std::time::Instant::now();
    let error = match tokio::time::timeout(DATABASE_WAIT, state.database.ping()).await {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(_) => Some(format!("no answer within {} s", DATABASE_WAIT.as_secs())),
    };
    let database = DatabaseHealth {
        backend: state.database.backend(),
        reachable: error.is_none(),
        latency_ms: started.elapsed().as_secs_f64() * 1e3,
        error,
    };
    let code = if database.reachable {
        StatusCode::OK
    } else {
        StatusCode::SERVICE_UNAVAILABLE
    };
    let health = Json(Health {
        status: if database.reachable {
            "ok"
        } else {
            "database_unreachable"
        },
        database,
        version: env!("CARGO_PKG_VERSION"),
        dem_files: state.dem.file_count(),
        buildings: state.source.summary(),
        roof_classifier: state.classifier.as_ref().map(|c| c.model_id().to_owned()),
    });
    (code, health)
}

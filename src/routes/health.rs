//! `GET /health`: is the server up, and what data does it have.

use crate::error::ErrorBody;
use crate::state::AppState;
use axum::Json;
use axum::extract::State;
use serde::Serialize;
use utoipa::ToSchema;

#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// Always `ok` when the server answers.
    #[schema(example = "ok")]
    pub status: &'static str,
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

/// Liveness and a summary of the configured data.
#[utoipa::path(get, path = "/health", tag = "service",
    responses(
        (status = 200, description = "The server is up", body = Health),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn health(State(state): State<AppState>) -> Json<Health> {
    Json(Health {
        status: "ok",
        version: env!("CARGO_PKG_VERSION"),
        dem_files: state.dem.file_count(),
        buildings: state.source.summary(),
        roof_classifier: state.classifier.as_ref().map(|c| c.model_id().to_owned()),
    })
}

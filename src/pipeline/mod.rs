//! The request pipeline, between the routes and the core: gathers what an area needs (its
//! buildings from the source, the DEM files), waits for a generation slot, runs the core's
//! [`SceneRequest`] on the blocking pool under the request timeout, and returns bytes with their
//! figures. It knows nothing of HTTP headers (`crate::routes` formats them) or of caching (the
//! routes ask `crate::cache` first and hand this pipeline to it on a miss).

mod tiles3d;

pub use crate::generation_stats::GenerationStats;
pub use tiles3d::{subtree, tileset_layout};

use crate::error::AppError;
use crate::source::AreaBuildings;
use crate::state::AppState;
use bytes::Bytes;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::scene::{SceneArea, SceneRequest};
use std::future::Future;
use std::sync::Arc;
use std::time::Instant;

/// A generated GLB and what went into it.
pub struct Generated {
    pub glb: Bytes,
    pub stats: GenerationStats,
}

/// Whose buildings stand in the scene.
pub enum Buildings {
    /// The server's source, for the area.
    FromSource,
    /// Buildings the request brought (procedural or uploaded).
    Given(Arc<BuildingSet>),
}

/// Runs `work` under the request timeout (503 `timeout` after it).
pub async fn within_timeout<T>(
    state: &AppState,
    work: impl Future<Output = Result<T, AppError>>,
) -> Result<T, AppError> {
    let limit = state.limits.request_timeout;
    tokio::time::timeout(limit, work)
        .await
        .map_err(|_| AppError::Unavailable {
            code: "timeout",
            detail: format!(
                "generating this area took longer than {} s; try a smaller area or again later",
                limit.as_secs_f64()
            ),
            retry_after_secs: 5,
        })?
}

/// Generates an area as GLB bytes: gathers its buildings (which may ask upstream), then waits for
/// a generation slot (503 when none frees up in time) and generates on the blocking pool. The
/// whole takes at most `--request-timeout-s` (503 after that). 3D Tiles content that holds no
/// building group is not generated: 404 `no_content`.
pub async fn generate(
    state: &AppState,
    area: SceneArea,
    buildings: Buildings,
) -> Result<Generated, AppError> {
    within_timeout(state, generate_within(state, area, buildings)).await
}

async fn generate_within(
    state: &AppState,
    area: SceneArea,
    buildings: Buildings,
) -> Result<Generated, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))?;
    let buildings = match buildings {
        Buildings::FromSource => state.source.buildings(&bbox).await?,
        Buildings::Given(set) => AreaBuildings {
            set,
            origin: "request".to_owned(),
        },
    };
    let _slot = tokio::time::timeout(
        state.limits.generation_wait,
        state.generations.clone().acquire_owned(),
    )
    .await
    .map_err(|_| AppError::Unavailable {
        code: "busy",
        detail:
            "every generation slot is busy: try again in a moment (cached tiles are still served)"
                .to_owned(),
        retry_after_secs: 1,
    })?
    .map_err(AppError::internal)?;
    let dem = state.dem.clone();
    let generated = tokio::task::spawn_blocking(move || {
        let started = Instant::now();
        let request: SceneRequest<'_> = area
            .request(&buildings.set)
            .map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))?;
        if matches!(area, SceneArea::Implicit { .. }) && request.groups.is_empty() {
            return Err(AppError::not_found(
                "no_content",
                "this tile has no content (see the subtree's availability)",
            ));
        }
        // Whole buildings may reach past the box: their ground must be loaded too.
        let lookup = dem.lookup(&request.terrain_bbox());
        let output = request.generate(&lookup.model);
        let stats = GenerationStats {
            generation_ms: started.elapsed().as_secs_f64() * 1e3,
            vertices: output.glb.vertices,
            triangles: output.glb.triangles,
            ground: output.ground,
            missing_dem: lookup.missing,
            buildings: output.buildings,
            osm: buildings.origin,
            groups: request.groups.len(),
        };
        Ok(Generated {
            glb: Bytes::from(output.glb.bytes),
            stats,
        })
    })
    .await??;
    state.metrics.generations.inc();
    state
        .metrics
        .generation_seconds
        .observe(generated.stats.generation_ms / 1e3);
    tracing::debug!(
        ms = generated.stats.generation_ms,
        bytes = generated.glb.len(),
        "generated"
    );
    Ok(generated)
}

//! The bridge from a request to the core generator: gathers the data an area needs, runs the
//! generator on the blocking pool, and returns the GLB with the figures that describe it.

use crate::error::AppError;
use crate::state::AppState;
use axum::http::{HeaderMap, HeaderName, HeaderValue, header};
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use citymesh_core::scene::Scene;
use std::time::Instant;

/// A generated GLB and what went into it.
pub struct Generated {
    pub glb: Bytes,
    pub stats: GenerationStats,
}

/// Figures of one generation, also sent as `X-Citymesh-*` response headers.
#[derive(Debug, Clone, Default)]
pub struct GenerationStats {
    pub generation_ms: f64,
    pub vertices: usize,
    pub triangles: usize,
    pub void_cells: usize,
    /// 1x1 degree areas without a DEM file, where the ground is the flat 0 m fallback.
    pub missing_dem: Vec<String>,
}

/// Generates the scene of `bbox` as GLB bytes.
pub async fn scene_glb(state: &AppState, bbox: GeoBbox) -> Result<Generated, AppError> {
    let dem = state.dem.clone();
    let generated = tokio::task::spawn_blocking(move || {
        let started = Instant::now();
        let lookup = dem.lookup(&bbox);
        let scene = Scene::ground(&lookup.model, &bbox);
        let glb = scene.to_glb();
        let stats = GenerationStats {
            generation_ms: started.elapsed().as_secs_f64() * 1e3,
            vertices: scene.mesh.positions.len(),
            triangles: scene.mesh.triangles.len(),
            void_cells: scene.ground.void_cells,
            missing_dem: lookup.missing,
        };
        Generated {
            glb: Bytes::from(glb),
            stats,
        }
    })
    .await?;
    tracing::debug!(%bbox, ms = generated.stats.generation_ms, bytes = generated.glb.len(), "scene generated");
    Ok(generated)
}

/// The headers every GLB response carries.
pub fn glb_headers(stats: Option<&GenerationStats>) -> HeaderMap {
    let mut h = HeaderMap::new();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("model/gltf-binary"),
    );
    let Some(s) = stats else { return h };
    let mut put = |name: &'static str, value: String| {
        if let Ok(v) = HeaderValue::from_str(&value) {
            h.insert(HeaderName::from_static(name), v);
        }
    };
    put(
        "x-citymesh-generation-ms",
        format!("{:.3}", s.generation_ms),
    );
    put("x-citymesh-vertices", s.vertices.to_string());
    put("x-citymesh-triangles", s.triangles.to_string());
    put("x-citymesh-void-cells", s.void_cells.to_string());
    let ground = if s.missing_dem.is_empty() {
        "dem".to_owned()
    } else {
        format!("flat-fallback; missing={}", s.missing_dem.join(","))
    };
    put("x-citymesh-ground", ground);
    h
}

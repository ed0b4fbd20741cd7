//! The bridge from a request to the core generator: gathers the data an area needs (DEM files,
//! the clusters of buildings), runs the generator on the blocking pool, and returns the GLB with
//! the figures that describe it.

use crate::error::AppError;
use crate::osm::AreaBuildings;
use crate::state::AppState;
use axum::http::{HeaderMap, HeaderName, HeaderValue, header};
use bytes::Bytes;
use citymesh_core::building::BuildingStats;
use citymesh_core::building::set::{BuildingSet, extent_with};
use citymesh_core::geo::{GeoBbox, ImplicitTile, TileCoord};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::GroundReport;
use std::sync::Arc;
use std::time::Instant;

/// What to generate.
#[derive(Debug, Clone)]
pub enum Area {
    /// A box, buildings cut at its border (`/scene.glb`).
    Scene(GeoBbox),
    /// An XYZ tile: the ground cut to the tile, whole buildings whose cluster's representative
    /// point lies in it.
    Tile(TileCoord),
    /// Given buildings (procedural or posted), whole, on the ground of a box.
    Buildings {
        bbox: GeoBbox,
        set: Arc<BuildingSet>,
    },
    /// A content tile of the implicit quadtree over `root` (3D Tiles): the ground of the tile
    /// and, whole, the buildings whose cluster's representative point it holds; in ECEF.
    Implicit { root: GeoBbox, tile: ImplicitTile },
}

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
    pub ground: GroundReport,
    /// 1x1 degree areas without a DEM file, where the ground is the flat 0 m fallback.
    pub missing_dem: Vec<String>,
    pub buildings: BuildingStats,
    /// Where the buildings came from: `files`, `stored`, or the data tiles missing offline.
    pub osm: String,
}

/// Generates an area as GLB bytes: gathers its buildings (which may ask upstream), then waits for
/// a generation slot (503 when none frees up in time) and generates on the blocking pool. The
/// whole takes at most `--request-timeout-s` (503 after that).
pub async fn generate(state: &AppState, area: Area) -> Result<Generated, AppError> {
    let limit = state.limits.request_timeout;
    tokio::time::timeout(limit, generate_within(state, area))
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

async fn generate_within(state: &AppState, area: Area) -> Result<Generated, AppError> {
    let buildings = match &area {
        Area::Scene(b) => state.osm.area(b).await?,
        Area::Tile(t) => state.osm.area(&t.bounds()).await?,
        Area::Buildings { set, .. } => AreaBuildings {
            set: set.clone(),
            origin: "request".to_owned(),
        },
        Area::Implicit { root, tile } => state.osm.area(&implicit_bbox(root, tile)?).await?,
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
        let set = &buildings.set;
        let (bbox, clusters, border) = match &area {
            Area::Scene(b) => (*b, set.clusters_intersecting(b), Border::Truncate),
            Area::Tile(t) => (t.bounds(), set.clusters_of_tile(t), Border::Whole),
            Area::Buildings { bbox, .. } => (*bbox, set.clusters().iter().collect(), Border::Whole),
            Area::Implicit { root, tile } => {
                let bbox = implicit_bbox(root, tile).unwrap_or(*root);
                let clusters = set
                    .clusters_intersecting(&bbox)
                    .into_iter()
                    .filter(|c| {
                        let (lon, lat) = c.representative_point();
                        root.contains(lon, lat)
                            && ImplicitTile::containing(root, tile.level, lon, lat) == *tile
                    })
                    .collect();
                (bbox, clusters, Border::Whole)
            }
        };
        // Whole buildings may reach past the box: their ground must be loaded too.
        let lookup = dem.lookup(&extent_with(&bbox, &clusters));
        let groups: Vec<_> = clusters.iter().map(|c| set.cluster_records(c)).collect();
        let scene = Scene::new(&lookup.model, &bbox, &groups, border);
        let glb = if matches!(area, Area::Implicit { .. }) {
            scene.to_glb_ecef()
        } else {
            scene.to_glb()
        };
        let stats = GenerationStats {
            generation_ms: started.elapsed().as_secs_f64() * 1e3,
            vertices: scene.mesh.positions.len(),
            triangles: scene.mesh.triangles.len(),
            ground: scene.ground,
            missing_dem: lookup.missing,
            buildings: scene.buildings,
            osm: buildings.origin,
        };
        Generated {
            glb: Bytes::from(glb),
            stats,
        }
    })
    .await?;
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

/// The box of an implicit tile.
pub fn implicit_bbox(root: &GeoBbox, tile: &ImplicitTile) -> Result<GeoBbox, AppError> {
    let [w, s, e, n] = tile.bounds(root);
    GeoBbox::new(w, s, e, n).map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))
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
    put("x-citymesh-void-cells", s.ground.void_cells.to_string());
    let ground = if s.missing_dem.is_empty() {
        "dem".to_owned()
    } else {
        format!("flat-fallback; missing={}", s.missing_dem.join(","))
    };
    put("x-citymesh-ground", ground);
    put("x-citymesh-osm", s.osm.clone());
    let b = &s.buildings;
    put("x-citymesh-buildings", b.generated.to_string());
    let skipped = if b.skipped.is_empty() {
        "0".to_owned()
    } else {
        let reasons: Vec<String> = b.skipped.iter().map(|(r, n)| format!("{r}={n}")).collect();
        format!("{}; {}", b.total_skipped(), reasons.join(","))
    };
    put("x-citymesh-buildings-skipped", skipped);
    put(
        "x-citymesh-flat-roofs-percent",
        format!("{:.1}", b.flat_roof_percent()),
    );
    put(
        "x-citymesh-roof-shapes-from-tags-percent",
        format!("{:.1}", b.shape_from_tag_percent()),
    );
    h
}

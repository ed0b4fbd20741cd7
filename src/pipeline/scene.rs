//! Scenes: an area's buildings and terrain through the core generator, on the blocking pool.

use super::Generator;
use super::limits::{generation_slot, within_timeout};
use crate::error::AppError;
use crate::generation_stats::GenerationStats;
use crate::pipeline::PipelineError;
use crate::source::AreaBuildings;
use bytes::Bytes;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::building::{HeightBase, TagProperties};
use citymesh_core::mesh::Encoding;
use citymesh_core::scene::{RoofChoice, SceneArea, SceneRequest};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Sets its flag when dropped.
struct SetOnDrop(Arc<AtomicBool>);

impl Drop for SetOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// A generated GLB and what went into it.
pub struct Generated {
    pub glb: Bytes,
    pub stats: GenerationStats,
    /// Served from the scene cache (the figures are those of its generation).
    pub from_cache: bool,
}

/// Whose buildings stand in the scene.
pub enum Buildings {
    /// The server's source, for the area.
    FromSource,
    /// Buildings the request brought (procedural or uploaded).
    Given(Arc<BuildingSet>),
    /// The source's buildings, loaded already (to choose roofs).
    Loaded(AreaBuildings),
}

/// Generates an area as GLB bytes: gathers its buildings (which may ask upstream), then waits for
/// a generation slot (503 when none frees up in time) and generates on the blocking pool. The
/// whole takes at most `--request-timeout-s` (503 after that). 3D Tiles content without a
/// building group is its ground alone.
/// `roofs` gives shapes to buildings without a `roof:shape` tag (classified roofs); `mesh` says
/// how the GLB stores vertices and where heights are counted from.
pub async fn generate(
    generator: &Generator,
    area: SceneArea,
    buildings: Buildings,
    roofs: Option<Arc<RoofChoice>>,
    mesh: MeshOptions,
) -> Result<Generated, AppError> {
    within_timeout(
        generator,
        generate_within(generator, area, buildings, roofs, mesh),
    )
    .await
}

/// The source's buildings of an area, gathered under the request timeout (which may ask
/// upstream, except for the world tileset's tiles): what a cached tile is generated from, gathered before its generation turn.
pub async fn gather(generator: &Generator, area: SceneArea) -> Result<AreaBuildings, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| PipelineError::InvalidArea(e.to_string()))?;
    within_timeout(generator, async {
        // The world tileset covers what the source holds: its tiles never ask upstream, but
        // for the leaves in the area it covers beyond that (`--world-area`).
        let fetches = generator.world_area.is_some_and(|a| a.overlaps(&bbox));
        Ok(match area {
            SceneArea::World(_) if !fetches => generator.source.held_area(&bbox).await?,
            _ => generator.source.buildings(&bbox).await?,
        })
    })
    .await
}

/// How a generated mesh is made beyond its area and buildings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshOptions {
    pub encoding: Encoding,
    /// The ground a building's `height` is counted from.
    pub heights: HeightBase,
    /// Whether each building carries every OSM tag too.
    pub tags: TagProperties,
}

impl MeshOptions {
    /// `encoding`, with heights as the server counts them (`--height-base`), the named
    /// properties only.
    pub fn new(generator: &Generator, encoding: Encoding) -> Self {
        Self {
            encoding,
            heights: generator.height_base,
            tags: TagProperties::default(),
        }
    }

    /// The same options, each building carrying the properties `tags` says.
    pub fn with_tags(self, tags: TagProperties) -> Self {
        Self { tags, ..self }
    }
}

async fn generate_within(
    generator: &Generator,
    area: SceneArea,
    buildings: Buildings,
    roofs: Option<Arc<RoofChoice>>,
    mesh: MeshOptions,
) -> Result<Generated, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| PipelineError::InvalidArea(e.to_string()))?;
    let buildings = match buildings {
        Buildings::FromSource => generator.source.buildings(&bbox).await?,
        Buildings::Given(set) => AreaBuildings::given(set),
        Buildings::Loaded(loaded) => loaded,
    };
    let slot = generation_slot(generator).await?;
    let dem = generator.dem.clone();
    let roof_method = generator.roof_method;
    let max_nodes = generator.limits.max_scene_nodes;
    // Set when this request is dropped (the client left, or the timeout fired): the blocking
    // work then stops before its next group of buildings and frees its slot.
    let gone = Arc::new(AtomicBool::new(false));
    let _on_drop = SetOnDrop(gone.clone());
    let generated = tokio::task::spawn_blocking(move || {
        // The slot goes with the work (see `limits::run_blocking`).
        let _slot = slot;
        let started = Instant::now();
        let mut request: SceneRequest<'_> = area
            .request(&buildings.set)
            .map_err(|e| PipelineError::InvalidArea(e.to_string()))?
            .with_encoding(mesh.encoding)
            .with_heights(mesh.heights)
            .with_roof_method(roof_method)
            .with_tags(mesh.tags);
        if let Some(roofs) = &roofs {
            request = request.with_roofs(roofs);
        }
        let nodes = request.outline_nodes();
        if nodes > max_nodes {
            return Err(AppError::from(PipelineError::TooComplex {
                nodes,
                max: max_nodes,
            }));
        }
        // Whole buildings may reach past the box: their ground must be loaded too.
        let lookup = dem.lookup(&request.terrain_bbox());
        let stop = || gone.load(Ordering::Relaxed);
        let Some(mut output) = request.generate_until(&lookup.model, &stop) else {
            return Err(AppError::from(PipelineError::Abandoned));
        };
        // What the data had but could not be built, and what was built with less: repairs of
        // the records this scene used (drawn, or drawn through their parts).
        let used: std::collections::HashSet<_> = request
            .groups
            .iter()
            .flat_map(|c| buildings.set.cluster_records(c))
            .map(|r| r.id)
            .collect();
        output
            .buildings
            .note_reading(&buildings.load_skips, &buildings.repaired, &|id| {
                used.contains(&id)
            });
        let stats = GenerationStats {
            generation_ms: started.elapsed().as_secs_f64() * 1e3,
            vertices: output.glb.vertices,
            triangles: output.glb.triangles,
            ground: output.ground,
            missing_dem: lookup.missing,
            buildings: output.buildings,
            osm: buildings.origin,
            groups: request.groups.len(),
            chosen_roofs: output.chosen_roofs,
            inferred_roofs: output.inferred_roofs,
        };
        Ok(Generated {
            glb: Bytes::from(output.glb.bytes),
            stats,
            from_cache: false,
        })
    })
    .await??;
    generator.metrics.generations.inc();
    generator
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

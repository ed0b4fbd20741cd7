//! The figures of one generation: reported in `X-Citymesh-*` headers (formatted in
//! `crate::routes`) and by `/scene/stats`.

use citymesh_core::building::BuildingStats;
use citymesh_core::terrain::GroundReport;

/// What one generation made and what went into it.
#[derive(Debug, Clone, Default)]
pub struct GenerationStats {
    pub generation_ms: f64,
    /// Vertices and triangles in the encoded file.
    pub vertices: usize,
    pub triangles: usize,
    pub ground: GroundReport,
    /// 1x1 degree areas without a DEM file, where the ground is the flat 0 m fallback.
    pub missing_dem: Vec<String>,
    pub buildings: BuildingStats,
    /// Where the buildings came from: `files`, `stored`, `request`, or the data tiles missing
    /// offline.
    pub osm: String,
    /// Groups of buildings in the scene.
    pub groups: usize,
    /// Buildings whose roof shape came from the classifier (counted in `buildings` as tagged).
    pub chosen_roofs: usize,
    /// Buildings whose roof shape came from the roof prior (counted in `buildings` as tagged).
    pub inferred_roofs: usize,
}

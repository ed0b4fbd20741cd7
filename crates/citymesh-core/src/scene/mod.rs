//! A scene: everything generated for one bounding box, in one local frame, ready to encode: the
//! ground grid and the buildings standing on it. [`SceneArea`] says, for every kind of area
//! citymesh serves, which box and which groups of buildings a scene holds.

mod request;
mod roof_choice;

pub use request::{SceneArea, SceneOutput, SceneRequest};
pub use roof_choice::RoofChoice;

use crate::building::{BuildingContext, BuildingStats, generate_cluster};
use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{EncodedGlb, Encoding, Mesh, Placement, encode_glb};
use crate::osm::BuildingRecord;
use crate::terrain::{ElevationModel, GroundReport, build_ground};
use std::ops::Range;

/// How buildings meet the border of the scene's box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Border {
    /// Cut at the border (`/scene`, docs/method.md section 5).
    Truncate,
    /// Kept whole (tiles: each cluster lands in exactly one tile).
    Whole,
}

/// The generated mesh of a bounding box and what went into it.
#[derive(Debug, Clone)]
pub struct Scene {
    pub frame: LocalFrame,
    pub mesh: Mesh,
    pub ground: GroundReport,
    pub buildings: BuildingStats,
    /// The triangles of each cluster of buildings, in order (for checks).
    pub cluster_triangles: Vec<Range<usize>>,
}

impl Scene {
    /// The ground of `bbox` from `model`, in a frame whose origin is the box centre at 0 m
    /// (mean sea level), so all tiles and scenes share one height reference.
    pub fn ground(model: &ElevationModel, bbox: &GeoBbox) -> Self {
        Self::new(model, bbox, &[], Border::Whole)
    }

    /// The ground of `bbox` and the buildings of `clusters` (each a list of records generated
    /// together, see [`crate::building::clusters`]).
    pub fn new(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        border: Border,
    ) -> Self {
        Self::build(model, bbox, clusters, border, &|| false).0
    }

    /// Like [`Scene::new`], but asks `stop` before each group of buildings and gives up (`None`)
    /// when it says so: a caller whose client has gone stops paying for the rest.
    pub fn new_until(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        border: Border,
        stop: &dyn Fn() -> bool,
    ) -> Option<Self> {
        let (scene, complete) = Self::build(model, bbox, clusters, border, stop);
        complete.then_some(scene)
    }

    /// The scene, and whether it is complete (`stop` never said so).
    fn build(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        border: Border,
        stop: &dyn Fn() -> bool,
    ) -> (Self, bool) {
        let (lon, lat) = bbox.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let mut mesh = Mesh::default();
        let ground = build_ground(model, bbox, &frame, &mut mesh);
        // Buildings make about 5 vertices and 4 triangles per outline node: reserving that
        // once spares the copies of a growing mesh.
        let nodes: usize = clusters
            .iter()
            .flatten()
            .flat_map(|b| b.outers.iter().chain(&b.inners))
            .map(|ring| ring.nodes.len())
            .sum();
        mesh.positions.reserve(nodes * 5);
        mesh.triangles.reserve(nodes * 4);
        mesh.styles.reserve(nodes * 4);
        let ctx = BuildingContext {
            frame: &frame,
            elevation: model,
            clip: (border == Border::Truncate).then_some(*bbox),
        };
        let mut buildings = BuildingStats::default();
        let mut cluster_triangles = Vec::with_capacity(clusters.len());
        let mut complete = true;
        for cluster in clusters {
            if stop() {
                complete = false;
                break;
            }
            let start = mesh.triangles.len();
            generate_cluster(cluster, &ctx, &mut mesh, &mut buildings);
            cluster_triangles.push(start..mesh.triangles.len());
        }
        let scene = Self {
            frame,
            mesh,
            ground,
            buildings,
            cluster_triangles,
        };
        (scene, complete)
    }

    /// The scene encoded as GLB with the given placement and encoding, its buildings' OSM ids
    /// recorded in the file.
    pub fn encode(&self, placement: Placement, encoding: Encoding) -> EncodedGlb {
        encode_glb(
            &self.mesh,
            &self.frame,
            placement,
            encoding,
            &self.buildings.generated_ids,
        )
    }

    /// The scene as plain GLB bytes in local glTF axes, its origin recorded in the file.
    pub fn to_glb(&self) -> Vec<u8> {
        self.encode(Placement::LocalEnu, Encoding::Plain).bytes
    }
}

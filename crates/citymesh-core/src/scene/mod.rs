//! A scene: everything generated for one bounding box, in one local frame, ready to encode: the
//! ground grid and the buildings standing on it. [`SceneArea`] says, for every kind of area
//! citymesh serves, which box and which groups of buildings a scene holds; [`level_of_detail`]
//! how coarse tiles above the 3D Tiles leaves simplify them.

mod level_of_detail;
mod request;
mod roof_choice;

pub use level_of_detail::{LevelOfDetail, Simplified};
pub use request::{SceneArea, SceneOutput, SceneRequest};
pub use roof_choice::{Chooser, RoofChoice};

use crate::building::feature::property_table;
use crate::building::{
    BuildingContext, BuildingStats, HeightBase, RoofMethod, TagProperties, generate_cluster_until,
};
use crate::geo::Region;
use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{EncodedGlb, Encoding, Mesh, Placement, encode_glb};
use crate::osm::BuildingRecord;
use crate::terrain::{CellMask, ElevationModel, GroundReport, build_coarse_ground, build_ground};
use std::ops::Range;

/// How the ground of a scene is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GroundDetail {
    /// Every cell of the elevation model (docs/method.md section 4).
    Dem,
    /// A regular grid of this many cells per side (coarse levels of detail).
    Grid(u32),
    /// A 16 x 16 grid, only its cells the mask holds (the world tree's blocks: ground where data is).
    Cells(CellMask),
}

/// How a scene is drawn, beyond its box and buildings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SceneRules {
    pub border: Border,
    pub ground: GroundDetail,
    /// The ground a building's `height` is counted from.
    pub heights: HeightBase,
    /// How hipped, gabled and pyramidal roofs are laid over their footprints.
    pub roof_method: RoofMethod,
    /// Whether each building carries every OSM tag too.
    pub tags: TagProperties,
}

impl SceneRules {
    /// Full detail, buildings meeting the border as `border` says, heights by Simple 3D Buildings.
    pub fn new(border: Border) -> Self {
        Self {
            border,
            ground: GroundDetail::Dem,
            heights: HeightBase::default(),
            roof_method: RoofMethod::default(),
            tags: TagProperties::default(),
        }
    }
}

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
        Self::build(model, bbox, clusters, SceneRules::new(border), &|| false, 1).0
    }

    /// Like [`Scene::new`], generated under `rules`.
    pub fn new_with_rules(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        rules: SceneRules,
    ) -> Self {
        Self::build(model, bbox, clusters, rules, &|| false, 1).0
    }

    /// Like [`Scene::new`], but asks `stop` before each group of buildings and gives up (`None`)
    /// when it says so (a caller whose client has gone stops paying for the rest), with the
    /// groups shared among `workers` threads (scoped, so the call stays synchronous). The result
    /// does not depend on `workers`, byte for byte: each thread builds a contiguous run of groups
    /// and the runs are joined in order.
    pub fn new_with_workers(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        border: Border,
        stop: &(dyn Fn() -> bool + Sync),
        workers: usize,
    ) -> Option<Self> {
        let (scene, complete) = Self::build(
            model,
            bbox,
            clusters,
            SceneRules::new(border),
            stop,
            workers,
        );
        complete.then_some(scene)
    }

    /// The scene, and whether it is complete (`stop` never said so).
    pub(super) fn build(
        model: &ElevationModel,
        bbox: &GeoBbox,
        clusters: &[Vec<&BuildingRecord>],
        rules: SceneRules,
        stop: &(dyn Fn() -> bool + Sync),
        workers: usize,
    ) -> (Self, bool) {
        let (lon, lat) = bbox.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let mut mesh = Mesh::default();
        let ground = match rules.ground {
            GroundDetail::Dem => build_ground(model, bbox, &frame, &mut mesh),
            GroundDetail::Grid(cells) => {
                build_coarse_ground(model, bbox, &frame, cells, None, &mut mesh)
            }
            GroundDetail::Cells(mask) => {
                build_coarse_ground(model, bbox, &frame, 16, Some(&mask), &mut mesh)
            }
        };
        let ctx = BuildingContext {
            frame: &frame,
            elevation: model,
            clip: (rules.border == Border::Truncate).then_some(*bbox),
            heights: rules.heights,
            roof_method: rules.roof_method,
            tags: rules.tags,
        };
        let runs = split_runs(clusters, workers);
        let (buildings, cluster_triangles, complete) = if runs.len() <= 1 {
            let built = build_groups(clusters, &ctx, stop, &mut mesh);
            (built.buildings, built.cluster_triangles, built.complete)
        } else {
            let parts: Vec<(Mesh, GroupsBuilt)> = std::thread::scope(|scope| {
                let ctx = &ctx;
                let handles: Vec<_> = runs
                    .iter()
                    .map(|run| {
                        scope.spawn(move || {
                            let mut part = Mesh::default();
                            let built = build_groups(&clusters[run.clone()], ctx, stop, &mut part);
                            (part, built)
                        })
                    })
                    .collect();
                // A thread's panic goes on in the caller, as it would have on one thread.
                handles
                    .into_iter()
                    .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                    .collect()
            });
            mesh.reserve_for(parts.iter().map(|(m, _)| m));
            let mut buildings = BuildingStats::default();
            let mut cluster_triangles = Vec::with_capacity(clusters.len());
            let mut complete = true;
            for (part, built) in parts {
                let offset = mesh.triangles.len();
                cluster_triangles.extend(
                    built
                        .cluster_triangles
                        .into_iter()
                        .map(|r| r.start + offset..r.end + offset),
                );
                // Each run numbered its buildings from 0: they follow the runs before.
                mesh.append_with_features(&part, buildings.features.len() as u32);
                buildings.absorb(built.buildings);
                complete &= built.complete;
            }
            (buildings, cluster_triangles, complete)
        };
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
    /// recorded in the file and each building's properties in its property table.
    pub fn encode(&self, placement: Placement, encoding: Encoding) -> EncodedGlb {
        let table = property_table(&self.buildings.features);
        encode_glb(
            &self.mesh,
            &self.frame,
            placement,
            encoding,
            &self.buildings.generated_ids(),
            Some(&table),
        )
    }

    /// Where the scene's vertices lie on the Earth: longitude and latitude in degrees, heights
    /// above the ellipsoid (as the ECEF placement puts them), or `None` for an empty scene.
    pub fn geographic_extent(&self) -> Option<Region> {
        Region::of_points(
            self.mesh
                .positions
                .iter()
                .map(|&p| self.frame.to_geographic(p)),
        )
    }

    /// The scene as plain GLB bytes in local glTF axes, its origin recorded in the file.
    pub fn to_glb(&self) -> Vec<u8> {
        self.encode(Placement::LocalEnu, Encoding::Plain).bytes
    }
}

/// What building a run of groups gave besides the mesh: figures and triangle ranges.
struct GroupsBuilt {
    buildings: BuildingStats,
    cluster_triangles: Vec<Range<usize>>,
    complete: bool,
}

/// Builds `clusters` in order into `mesh`, asking `stop` before each.
fn build_groups(
    clusters: &[Vec<&BuildingRecord>],
    ctx: &BuildingContext<'_>,
    stop: &(dyn Fn() -> bool + Sync),
    mesh: &mut Mesh,
) -> GroupsBuilt {
    // Buildings make about 6 vertices and 4.5 triangles per outline node (Kirchfeld): reserving
    // a little more once spares the copies of a growing mesh (pages never written cost nothing).
    let nodes = outline_nodes(clusters);
    mesh.positions.reserve(nodes * 7);
    mesh.triangles.reserve(nodes * 5);
    mesh.styles.reserve(nodes * 5);
    let mut buildings = BuildingStats::default();
    let mut cluster_triangles = Vec::with_capacity(clusters.len());
    for cluster in clusters {
        if stop() {
            return GroupsBuilt {
                buildings,
                cluster_triangles,
                complete: false,
            };
        }
        let start = mesh.triangles.len();
        generate_cluster_until(cluster, ctx, mesh, &mut buildings, stop);
        cluster_triangles.push(start..mesh.triangles.len());
    }
    GroupsBuilt {
        buildings,
        cluster_triangles,
        // The last group may have stopped half way.
        complete: !stop(),
    }
}

fn outline_nodes(clusters: &[Vec<&BuildingRecord>]) -> usize {
    ring_nodes(clusters.iter().flatten().copied())
}

/// The nodes of the records' rings, outer and inner: what building them costs grows with.
pub(super) fn ring_nodes<'r>(records: impl IntoIterator<Item = &'r BuildingRecord>) -> usize {
    records
        .into_iter()
        .flat_map(|b| b.outers.iter().chain(&b.inners))
        .map(|ring| ring.nodes.len())
        .sum()
}

/// Contiguous runs of groups with about the same number of outline nodes, one per worker (fewer
/// when there is little to share: a run under 2,000 nodes is not worth a thread).
fn split_runs(clusters: &[Vec<&BuildingRecord>], workers: usize) -> Vec<Range<usize>> {
    const MIN_NODES_PER_RUN: usize = 2_000;
    let total = outline_nodes(clusters);
    let runs = workers.clamp(1, (total / MIN_NODES_PER_RUN).max(1));
    if runs <= 1 {
        return std::iter::once(0..clusters.len()).collect();
    }
    let per_run = total.div_ceil(runs);
    let mut out = Vec::with_capacity(runs);
    let (mut start, mut acc) = (0, 0);
    for (i, c) in clusters.iter().enumerate() {
        acc += outline_nodes(std::slice::from_ref(c));
        if acc >= per_run * (out.len() + 1) && out.len() + 1 < runs {
            out.push(start..i + 1);
            start = i + 1;
        }
    }
    out.push(start..clusters.len());
    out
}

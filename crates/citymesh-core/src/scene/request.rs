//! What a scene holds, for every kind of area citymesh serves: a box cut at its border, an XYZ
//! tile, a content tile of the 3D Tiles quadtree, or buildings a user gave. Each area decides its
//! ground box, the groups of buildings it includes (each group whole in exactly one tile of a
//! tiling, see [`crate::building::set::ClusterInfo`]), how buildings meet the border, and how the
//! result is placed on the Earth. Servers build one [`SceneRequest`] and hand it the data.

use super::level_of_detail::{LevelOfDetail, Simplified};
use super::{Border, GroundDetail, RoofChoice, Scene, SceneRules};
use crate::building::set::{BuildingSet, ClusterInfo, extent_with};
use crate::building::{
    BuildingRules, BuildingStats, HeightBase, RoofMethod, RoofOrigin, TagProperties,
};
use crate::geo::{BboxError, GeoBbox, ImplicitTile, LocalFrame, TileCoord};
use crate::mesh::{EncodedGlb, Encoding, Placement};
use crate::osm::BuildingRecord;
use crate::terrain::{CellMask, ElevationModel, GroundReport};
use crate::tiles3d::LEAF_ZOOM;
use std::borrow::Cow;

/// An area to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SceneArea {
    /// A box; buildings are cut at its border.
    Bbox(GeoBbox),
    /// An XYZ tile: the ground cut to the tile and, whole, the groups whose representative point
    /// lies in it.
    Xyz(TileCoord),
    /// A tile of the implicit quadtree over `root` (3D Tiles content): the ground of the tile
    /// and, whole, the groups it holds; placed in ECEF.
    Implicit { root: GeoBbox, tile: ImplicitTile },
    /// A tile of the world tree (`crate::tiles3d::world`), placed in ECEF: from the data tiles'
    /// zoom down, the ground cut to the tile and, whole, the groups whose representative point
    /// lies in it, roofs flattened above the leaves; above it, every group of the set it is
    /// given (the tile's blocks) on a coarse ground grid.
    World(TileCoord),
    /// A tile of the world tree above the data tiles: every group of the set it is given (the
    /// tile's blocks) on a coarse ground grid over the cells `ground` holds, in ECEF.
    Blocks { tile: TileCoord, ground: CellMask },
    /// Every group of a given set of buildings (procedural or uploaded), whole, on the ground of
    /// the box.
    Given(GeoBbox),
}

impl SceneArea {
    /// The box of ground the scene covers (an error only for an implicit tile too small to have
    /// distinct degrees).
    pub fn bbox(&self) -> Result<GeoBbox, BboxError> {
        match self {
            SceneArea::Bbox(b) | SceneArea::Given(b) => Ok(*b),
            SceneArea::Xyz(t) | SceneArea::World(t) | SceneArea::Blocks { tile: t, .. } => {
                Ok(t.bounds())
            }
            SceneArea::Implicit { root, tile } => tile.bbox(root),
        }
    }

    /// How buildings meet the border.
    pub fn border(&self) -> Border {
        match self {
            SceneArea::Bbox(_) => Border::Truncate,
            _ => Border::Whole,
        }
    }

    /// How the result is placed on the Earth.
    pub fn placement(&self) -> Placement {
        match self {
            SceneArea::Implicit { .. } | SceneArea::World(_) | SceneArea::Blocks { .. } => {
                Placement::Ecef
            }
            _ => Placement::LocalEnu,
        }
    }

    /// The request for this area over `set`: its box and the groups it includes.
    pub fn request<'a>(&self, set: &'a BuildingSet) -> Result<SceneRequest<'a>, BboxError> {
        let bbox = self.bbox()?;
        let groups = match self {
            SceneArea::Bbox(b) => set.clusters_intersecting(b),
            SceneArea::Xyz(t) => set.clusters_of_tile(t),
            SceneArea::Implicit { root, tile } => set.clusters_of_implicit_tile(root, tile),
            SceneArea::World(t) => set.clusters_of_tile(t),
            SceneArea::Blocks { .. } | SceneArea::Given(_) => set.clusters().iter().collect(),
        };
        // Implicit tiles above the leaves are coarser (docs/method.md, levels of detail).
        let detail = match self {
            SceneArea::Implicit { root, tile } => LevelOfDetail {
                above_leaves: ImplicitTile::leaf_level(root).saturating_sub(tile.level),
                dem_ground: false,
            },
            SceneArea::World(t) => LevelOfDetail {
                above_leaves: LEAF_ZOOM.saturating_sub(t.z),
                dem_ground: true,
            },
            SceneArea::Blocks { tile, .. } => LevelOfDetail {
                above_leaves: LEAF_ZOOM.saturating_sub(tile.z),
                dem_ground: false,
            },
            _ => LevelOfDetail::default(),
        };
        let ground_cells = match self {
            SceneArea::Blocks { ground, .. } => Some(*ground),
            _ => None,
        };
        Ok(SceneRequest {
            ground_cells,
            set,
            bbox,
            groups,
            border: self.border(),
            placement: self.placement(),
            encoding: Encoding::default(),
            roofs: None,
            workers: 1,
            detail,
            heights: HeightBase::default(),
            roof_method: RoofMethod::default(),
            tags: TagProperties::default(),
        })
    }
}

/// Everything the generator needs for one scene.
#[derive(Debug, Clone)]
pub struct SceneRequest<'a> {
    pub set: &'a BuildingSet,
    /// The ground's box.
    pub bbox: GeoBbox,
    /// The groups of buildings to generate, each with all its records.
    pub groups: Vec<&'a ClusterInfo>,
    pub border: Border,
    pub placement: Placement,
    /// How the GLB stores vertices.
    pub encoding: Encoding,
    /// Roof shapes for records without a `roof:shape` tag (none: tags and defaults only).
    pub roofs: Option<&'a RoofChoice>,
    /// Threads the groups of buildings are shared among (1: the calling thread only). The
    /// output does not depend on it.
    pub workers: usize,
    /// How coarse the content is (full detail but for implicit tiles above the leaves).
    pub detail: LevelOfDetail,
    /// The ground a building's `height` is counted from.
    pub heights: HeightBase,
    /// How hipped, gabled and pyramidal roofs are laid over their footprints.
    pub roof_method: RoofMethod,
    /// At a coarse level, the cells of the 16 x 16 ground grid to draw (`None`: all).
    pub ground_cells: Option<CellMask>,
    /// Whether each building carries every OSM tag too.
    pub tags: TagProperties,
}

/// A generated, encoded scene and what went into it.
#[derive(Debug, Clone)]
pub struct SceneOutput {
    pub glb: EncodedGlb,
    pub ground: GroundReport,
    pub buildings: BuildingStats,
    /// Generated records whose roof shape the classifier chose through the [`RoofChoice`]
    /// (counted by the core's statistics as tagged).
    pub chosen_roofs: usize,
    /// Generated records whose roof shape the roof prior chose (also counted as tagged).
    pub inferred_roofs: usize,
}

impl<'a> SceneRequest<'a> {
    /// The box the elevation model must cover: the ground and every whole group reaching past
    /// it.
    pub fn terrain_bbox(&self) -> GeoBbox {
        extent_with(&self.bbox, &self.groups)
    }

    /// The same request with roof shapes chosen for records that have no `roof:shape`.
    pub fn with_roofs(self, roofs: &'a RoofChoice) -> Self {
        Self {
            roofs: Some(roofs),
            ..self
        }
    }

    /// The same request built on up to `workers` threads.
    pub fn with_workers(self, workers: usize) -> Self {
        Self {
            workers: workers.max(1),
            ..self
        }
    }

    /// The same request with heights counted from `heights`.
    pub fn with_heights(self, heights: HeightBase) -> Self {
        Self { heights, ..self }
    }

    /// The same request generated under `rules`.
    pub fn with_rules(self, rules: BuildingRules) -> Self {
        self.with_heights(rules.heights)
            .with_roof_method(rules.roof_method)
    }

    /// The same request with roofs laid as `roof_method` says.
    pub fn with_roof_method(self, roof_method: RoofMethod) -> Self {
        Self {
            roof_method,
            ..self
        }
    }

    /// The same request encoded with `encoding`.
    pub fn with_encoding(self, encoding: Encoding) -> Self {
        Self { encoding, ..self }
    }

    /// The same request, its buildings carrying the properties `tags` says.
    pub fn with_tags(self, tags: TagProperties) -> Self {
        Self { tags, ..self }
    }

    /// The outline nodes (outer and inner rings) of the groups' records: what the work and
    /// memory of [`SceneRequest::generate`] grow with (about 6 vertices and 4.5 triangles per
    /// node).
    pub fn outline_nodes(&self) -> usize {
        super::ring_nodes(self.groups.iter().flat_map(|c| self.set.cluster_records(c)))
    }

    /// Each group's records as the generator sees them (with chosen roofs applied, and only
    /// those marked as chosen; simplified at a coarse level of detail, groups left empty left
    /// out).
    fn group_records(&self) -> Vec<Vec<Cow<'a, BuildingRecord>>> {
        let frame = self.frame();
        self.groups
            .iter()
            .map(|c| {
                let records = self
                    .set
                    .cluster_records(c)
                    .into_iter()
                    .map(RoofChoice::unmarked);
                let chosen: Vec<Cow<'a, BuildingRecord>> = match self.roofs {
                    Some(roofs) if !roofs.is_empty() => records.map(|r| roofs.apply(r)).collect(),
                    _ => records.collect(),
                };
                if self.detail.is_full() {
                    return chosen;
                }
                chosen
                    .into_iter()
                    .map(|r| self.detail.simplify(r, &frame, self.roof_method).0)
                    .collect()
            })
            .filter(|g: &Vec<_>| !g.is_empty())
            .collect()
    }

    /// The frame the scene is built in: the box's centre at 0 m.
    fn frame(&self) -> LocalFrame {
        let (lon, lat) = self.bbox.center();
        LocalFrame::new(lon, lat, 0.0)
    }

    /// The largest height this request's level of detail does not draw (its geometric error,
    /// m): half a flattened roof's, or the coarse ground's distance from the model. 0 at full
    /// detail.
    pub fn hidden_height(&self, model: &ElevationModel) -> f64 {
        if self.detail.is_full() {
            return 0.0;
        }
        let frame = self.frame();
        let mut worst = LevelOfDetail::ground_error(&self.bbox, model);
        for c in &self.groups {
            for r in self.set.cluster_records(c) {
                let hidden = match self
                    .detail
                    .simplify(Cow::Borrowed(r), &frame, self.roof_method)
                    .1
                {
                    Simplified::Kept => 0.0,
                    Simplified::Flattened { hidden_m } => hidden_m,
                };
                worst = worst.max(hidden);
            }
        }
        worst
    }

    /// The scene over `model` (which should cover [`SceneRequest::terrain_bbox`]).
    pub fn scene(&self, model: &ElevationModel) -> Scene {
        self.build(model, &|| false, 1).0
    }

    /// The scene over `model`, encoded.
    pub fn generate(&self, model: &ElevationModel) -> SceneOutput {
        let (scene, _) = self.build(model, &|| false, self.workers);
        Self::output(scene, self.placement, self.encoding)
    }

    /// Like [`SceneRequest::generate`], but gives up (`None`) as soon as `stop` says so (asked
    /// before each group of buildings, and before encoding).
    pub fn generate_until(
        &self,
        model: &ElevationModel,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<SceneOutput> {
        let (scene, complete) = self.build(model, stop, self.workers);
        (complete && !stop()).then(|| Self::output(scene, self.placement, self.encoding))
    }

    /// The scene and whether `stop` let it finish; a coarse level of detail has the grid
    /// ground.
    fn build(
        &self,
        model: &ElevationModel,
        stop: &(dyn Fn() -> bool + Sync),
        workers: usize,
    ) -> (Scene, bool) {
        let records = self.group_records();
        let ground = match (self.detail.grid_ground(), self.ground_cells) {
            (false, _) => GroundDetail::Dem,
            (true, Some(mask)) => GroundDetail::Cells(mask),
            (true, None) => GroundDetail::Grid(LevelOfDetail::GROUND_CELLS),
        };
        let rules = SceneRules {
            border: self.border,
            ground,
            heights: self.heights,
            roof_method: self.roof_method,
            tags: self.tags,
        };
        Scene::build(model, &self.bbox, &as_refs(&records), rules, stop, workers)
    }

    fn output(scene: Scene, placement: Placement, encoding: Encoding) -> SceneOutput {
        let (mut chosen_roofs, mut inferred_roofs) = (0, 0);
        for f in &scene.buildings.features {
            match f.roof_origin {
                RoofOrigin::Classifier { .. } => chosen_roofs += 1,
                RoofOrigin::Inferred { .. } => inferred_roofs += 1,
                _ => {}
            }
        }
        SceneOutput {
            glb: scene.encode(placement, encoding),
            ground: scene.ground,
            buildings: scene.buildings,
            chosen_roofs,
            inferred_roofs,
        }
    }
}

/// Borrowed views of each group's records.
fn as_refs<'r>(records: &'r [Vec<Cow<'_, BuildingRecord>>]) -> Vec<Vec<&'r BuildingRecord>> {
    records
        .iter()
        .map(|g| g.iter().map(AsRef::as_ref).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedural::{ProceduralParams, generate_city};

    #[test]
    fn each_group_is_in_exactly_one_tile_of_each_tiling() {
        let city = generate_city(&ProceduralParams::default()).unwrap();
        let set = BuildingSet::new(city.records);
        let all = set.clusters().len();
        assert!(all > 100, "{all} groups");
        // XYZ zoom 17 over the city.
        let range = TileCoord::covering(&city.bbox, 17);
        let xyz: usize = range
            .tiles()
            .map(|t| SceneArea::Xyz(t).request(&set).unwrap().groups.len())
            .sum();
        assert_eq!(xyz, all);
        // The implicit quadtree over a root holding the whole city, level 3.
        let root = set.extent().unwrap().grown_by_metres(10.0);
        let mut implicit = 0;
        for x in 0..8 {
            for y in 0..8 {
                let tile = ImplicitTile { level: 3, x, y };
                implicit += SceneArea::Implicit { root, tile }
                    .request(&set)
                    .unwrap()
                    .groups
                    .len();
            }
        }
        assert_eq!(implicit, all);
        let with_content = set.implicit_tiles_with_content(&root, 3);
        assert!(with_content.len() > 1 && with_content.len() <= 64);
    }

    #[test]
    fn generation_stops_when_asked_and_otherwise_matches() {
        let city = generate_city(&ProceduralParams::default()).unwrap();
        let set = BuildingSet::new(city.records);
        let request = SceneArea::Given(city.bbox).request(&set).unwrap();
        let model = ElevationModel::default();
        assert!(request.generate_until(&model, &|| true).is_none());
        // Asked before each group, each building and each group's meshing: stopping half way
        // gives nothing, and nothing more is asked once it has said stop.
        let asked = std::sync::atomic::AtomicUsize::new(0);
        let total = std::sync::atomic::AtomicUsize::new(0);
        let count = || {
            total.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            false
        };
        assert!(request.generate_until(&model, &count).is_some());
        let half = total.load(std::sync::atomic::Ordering::SeqCst) / 2;
        assert!(half > request.groups.len() / 2, "{half}");
        let stop = || asked.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1 > half;
        assert!(request.generate_until(&model, &stop).is_none());
        // After the first "stop": the group's own check, the groups loop's, and the last one.
        assert!(asked.load(std::sync::atomic::Ordering::SeqCst) <= half + 3);
        let whole = request.generate_until(&model, &|| false).unwrap();
        assert_eq!(whole.glb, request.generate(&model).glb);
    }

    #[test]
    fn chosen_roofs_fill_missing_tags_only() {
        let mut city = generate_city(&ProceduralParams::default()).unwrap();
        // Strip the tag of the first ten buildings (not parts) and choose hipped for them, and
        // for one building that keeps its tag.
        let mut choice = RoofChoice::new();
        let mut stripped = 0;
        for r in city.records.iter_mut().filter(|r| !r.is_part).take(11) {
            if stripped < 10 {
                r.tags.remove("roof:shape");
                stripped += 1;
            }
            choice.insert(r.id, crate::building::roof::RoofShape::Hipped, 0.9);
        }
        let set = BuildingSet::new(city.records);
        let model = ElevationModel::default();
        let plain = SceneArea::Given(city.bbox).request(&set).unwrap();
        let without = plain.generate(&model);
        let with = plain.clone().with_roofs(&choice).generate(&model);
        assert_eq!(without.chosen_roofs, 0);
        assert_eq!(with.chosen_roofs, 10);
        let hipped = |o: &SceneOutput| o.buildings.roof_shapes.get("hipped").copied().unwrap_or(0);
        let defaults = |o: &SceneOutput| o.buildings.shape_default;
        assert_eq!(defaults(&without) - defaults(&with), 10);
        // Every stripped building got a hipped roof; the tagged one kept its own shape.
        assert_eq!(hipped(&with), hipped(&without) + 10);
        assert_ne!(with.glb, without.glb);
        // An empty choice is the plain scene, byte for byte.
        let empty = RoofChoice::new();
        assert_eq!(
            plain.clone().with_roofs(&empty).generate(&model).glb,
            without.glb
        );
    }

    #[test]
    fn areas_choose_border_and_placement() {
        let b = GeoBbox::new(8.39, 49.04, 8.41, 49.06).unwrap();
        assert_eq!(SceneArea::Bbox(b).border(), Border::Truncate);
        assert_eq!(SceneArea::Given(b).border(), Border::Whole);
        let tile = ImplicitTile {
            level: 1,
            x: 1,
            y: 0,
        };
        let implicit = SceneArea::Implicit { root: b, tile };
        assert_eq!(implicit.placement(), Placement::Ecef);
        let got = implicit.bbox().unwrap();
        let want = [8.4, 49.04, 8.41, 49.05];
        let have = [got.min_lon(), got.min_lat(), got.max_lon(), got.max_lat()];
        for (h, w) in have.iter().zip(want) {
            assert!((h - w).abs() < 1e-12, "{have:?}");
        }
        assert_eq!(SceneArea::Bbox(b).placement(), Placement::LocalEnu);
    }
}

//! The tileset JSON of a region with implicit quadtree tiling.

use crate::building::feature::BUILDING_CLASS;
use crate::building::set::BuildingSet;
use crate::building::tags::parse_length;
use crate::geo::{GeoBbox, LocalFrame};
use crate::terrain::ElevationModel;
use serde_json::{Value, json};

/// Ground samples per side when measuring a region's height range.
const HEIGHT_SAMPLES: u32 = 33;
/// Height assumed for the tallest building when none is tagged taller (metres).
const MIN_TALLEST_M: f64 = 60.0;
/// Slack below the lowest ground and above the highest roof (metres).
const HEIGHT_SLACK_M: f64 = 20.0;

/// Content tiles are at most this wide (metres).
pub const LEAF_SIZE_M: f64 = 400.0;

/// The shape of the implicit tree over a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitLayout {
    pub root: GeoBbox,
    /// The level content is at (the deepest).
    pub leaf_level: u8,
    /// Heights of the region's bounding volume (metres).
    pub min_height: f64,
    pub max_height: f64,
}

impl ImplicitLayout {
    /// Leaves at most [`LEAF_SIZE_M`] wide.
    pub fn new(root: GeoBbox, min_height: f64, max_height: f64) -> Self {
        Self {
            root,
            leaf_level: Self::leaf_level_of(&root),
            min_height,
            max_height,
        }
    }

    /// The tree over `root` with its height range: the ground sampled on a 33 x 33 grid of
    /// `model`, and the tallest tagged building of `set` there (at least 60 m), with 20 m of slack.
    pub fn measure(root: GeoBbox, model: &ElevationModel, set: &BuildingSet) -> Self {
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        let last = f64::from(HEIGHT_SAMPLES - 1);
        for i in 0..HEIGHT_SAMPLES {
            for j in 0..HEIGHT_SAMPLES {
                let lon = root.min_lon() + (root.max_lon() - root.min_lon()) * f64::from(i) / last;
                let lat = root.min_lat() + (root.max_lat() - root.min_lat()) * f64::from(j) / last;
                let h = model.ground_height(lon, lat);
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        let tallest = set
            .clusters_intersecting(&root)
            .iter()
            .flat_map(|c| set.cluster_records(c))
            .filter_map(|r| r.tags.get("height").and_then(|h| parse_length(h)))
            .fold(MIN_TALLEST_M, f64::max);
        Self::new(root, lo - HEIGHT_SLACK_M, hi + tallest + HEIGHT_SLACK_M)
    }

    /// The level whose tiles are at most [`LEAF_SIZE_M`] wide: it depends on the region alone.
    pub fn leaf_level_of(root: &GeoBbox) -> u8 {
        let (lon, lat) = root.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        let side =
            ((root.max_lon() - root.min_lon()) * mx).max((root.max_lat() - root.min_lat()) * my);
        (side / LEAF_SIZE_M).log2().ceil().clamp(0.0, 12.0) as u8
    }

    pub fn available_levels(&self) -> u8 {
        self.leaf_level + 1
    }

    /// The geometric error of the root. Only the leaves have content (there are no coarser
    /// meshes), so the errors are large enough that clients refine to the leaves whenever the
    /// region is in view: the root's is the region's size, and the leaves' that over 2^levels.
    pub fn root_error(&self) -> f64 {
        let (lon, lat) = self.root.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        let w = (self.root.max_lon() - self.root.min_lon()) * mx;
        let h = (self.root.max_lat() - self.root.min_lat()) * my;
        4.0 * w.hypot(h)
    }
}

/// The tileset; `prefix` is put before the content and subtree templates (relative URIs). It
/// declares the schema of the buildings' property tables in its content.
pub fn tileset_json(layout: &ImplicitLayout, prefix: &str) -> Value {
    let r = &layout.root;
    let region = [
        r.min_lon().to_radians(),
        r.min_lat().to_radians(),
        r.max_lon().to_radians(),
        r.max_lat().to_radians(),
        layout.min_height,
        layout.max_height,
    ];
    json!({
        "asset": {"version": "1.1", "generator": concat!("citymesh ", env!("CARGO_PKG_VERSION"))},
        "schema": BUILDING_CLASS.schema(),
        "geometricError": layout.root_error() * 2.0,
        "root": {
            "boundingVolume": {"region": region},
            "refine": "REPLACE",
            "geometricError": layout.root_error(),
            "content": {"uri": format!("{prefix}content/{{level}}/{{x}}/{{y}}.glb")},
            "implicitTiling": {
                "subdivisionScheme": "QUADTREE",
                "availableLevels": layout.available_levels(),
                "subtreeLevels": layout.available_levels(),
                "subtrees": {"uri": format!("{prefix}subtrees/{{level}}/{{x}}/{{y}}.subtree")}
            }
        }
    })
}

//! Bounding regions of every tile of the implicit tree, measured on its content: a leaf's region
//! is the extent of its ground and of the whole buildings it holds (which may reach past the
//! tile's square), a parent's the union of its children's. The subtree carries them as tile
//! metadata with the semantic `TILE_BOUNDING_REGION`, so a client's bounding volume encloses
//! the content and its heights are tight.

use crate::building::BuildingRules;
use crate::building::set::BuildingSet;
use crate::geo::{GeoBbox, ImplicitTile, Region, morton};
use crate::scene::{RoofChoice, SceneArea, SceneRequest};
use crate::terrain::ElevationModel;

/// Slack around measured content, metres: vertices are stored as f32 or in quantization steps
/// of a few millimetres, and the region must still hold them.
const SLACK_M: f64 = 0.05;

/// The regions and geometric errors of every tile of a tree whose leaves are at `leaf_level`,
/// level by level, each level in Morton order (the order of the subtree's availability).
#[derive(Debug, Clone, PartialEq)]
pub struct TileRegions {
    pub leaf_level: u8,
    levels: Vec<Vec<(Region, f64)>>,
}

impl TileRegions {
    /// From each tile's measured content: its region (`None`: no content, the tile's square at
    /// `empty` heights) and the height its level of detail does not draw. A tile's region holds
    /// its content with [`SLACK_M`] around it and its children's regions; its geometric error is
    /// the larger of its own and its children's (0 at the leaves).
    pub fn new(
        root: &GeoBbox,
        leaf_level: u8,
        content: &mut dyn FnMut(ImplicitTile) -> Option<(Region, f64)>,
        empty: (f64, f64),
    ) -> Self {
        let mut levels: Vec<Vec<(Region, f64)>> = Vec::with_capacity(usize::from(leaf_level) + 1);
        for level in (0..=leaf_level).rev() {
            let n = 1u32 << level;
            let below = levels.last();
            let mut here = vec![None; (n as usize) * (n as usize)];
            for x in 0..n {
                for y in 0..n {
                    let t = ImplicitTile { level, x, y };
                    let square = || {
                        let [w, s, e, no] = t.bounds(root);
                        (
                            Region {
                                west: w,
                                south: s,
                                east: e,
                                north: no,
                                min_height: empty.0,
                                max_height: empty.1,
                            },
                            0.0,
                        )
                    };
                    let (own, own_error) = content(t).unwrap_or_else(square);
                    let m = morton(x, y) as usize;
                    let mut region = own.grown(SLACK_M);
                    let mut error = if level == leaf_level { 0.0 } else { own_error };
                    // In Morton order a tile's four children are consecutive.
                    if let Some(children) = below.and_then(|b| b.get(4 * m..4 * m + 4)) {
                        for (r, e) in children {
                            region = region.union(r);
                            error = error.max(*e);
                        }
                    }
                    here[m] = Some((region, error));
                }
            }
            levels.push(here.into_iter().flatten().collect());
        }
        levels.reverse();
        Self { leaf_level, levels }
    }

    /// The region of a tile of the tree.
    pub fn get(&self, t: ImplicitTile) -> Option<Region> {
        self.entry(t).map(|(r, _)| r)
    }

    /// The geometric error of a tile of the tree (metres; 0 at the leaves).
    pub fn error(&self, t: ImplicitTile) -> Option<f64> {
        self.entry(t).map(|(_, e)| e)
    }

    fn entry(&self, t: ImplicitTile) -> Option<(Region, f64)> {
        self.levels
            .get(usize::from(t.level))?
            .get(morton(t.x, t.y) as usize)
            .copied()
    }

    /// Every tile's region and geometric error, level by level in Morton order.
    pub fn all(&self) -> impl Iterator<Item = &(Region, f64)> {
        self.levels.iter().flatten()
    }
}

/// The regions and geometric errors of the tree over `root` with leaves at `leaf_level`,
/// measured by generating each tile's content (coarser above the leaves) from `set` on the
/// model `model_for` gives for its terrain box with heights counted from `heights`, once per roof
/// variant in `variants` (none: roofs from tags alone), so that content made with any of them
/// lies inside. `stop` is asked before
/// each tile; `None` when it said so.
pub fn measure_regions(
    root: &GeoBbox,
    leaf_level: u8,
    set: &BuildingSet,
    model_for: &dyn Fn(&GeoBbox) -> ElevationModel,
    variants: &[RoofChoice],
    rules: BuildingRules,
    stop: &dyn Fn() -> bool,
) -> Option<TileRegions> {
    let mut stopped = false;
    let regions = TileRegions::new(
        root,
        leaf_level,
        &mut |tile| {
            if stopped || stop() {
                stopped = true;
                return None;
            }
            let request = SceneArea::Implicit { root: *root, tile }
                .request(set)
                .ok()?
                .with_rules(rules);
            let model = model_for(&request.terrain_bbox());
            let extent = |r: &SceneRequest<'_>| r.scene(&model).geographic_extent();
            let mut region = extent(&request);
            for choice in variants {
                let other = extent(&request.clone().with_roofs(choice));
                region = match (region, other) {
                    (Some(a), Some(b)) => Some(a.union(&b)),
                    (a, b) => a.or(b),
                };
            }
            region.map(|r| (r, request.hidden_height(&model)))
        },
        (0.0, 0.0),
    );
    (!stopped).then_some(regions)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parents_hold_their_children_and_leaves_their_content() {
        let root = GeoBbox::new(8.0, 49.0, 8.02, 49.02).unwrap();
        // One leaf holds a building reaching 10 m past its east side, 30 m high.
        let tall = ImplicitTile {
            level: 2,
            x: 1,
            y: 2,
        };
        let regions = TileRegions::new(
            &root,
            2,
            &mut |t| {
                let [w, s, e, n] = t.bounds(&root);
                let east = if t == tall { e + 10.0 / 73_000.0 } else { e };
                let top = if t == tall { 130.0 } else { 100.0 };
                // Coarser tiles hide more: 2 m per level above the leaves.
                let error = 2.0 * f64::from(2 - t.level);
                let r = Region {
                    west: w,
                    south: s,
                    east,
                    north: n,
                    min_height: 90.0,
                    max_height: top,
                };
                (t.level == 2).then_some((r, error)).or(Some((
                    Region {
                        max_height: 95.0,
                        ..r
                    },
                    error,
                )))
            },
            (0.0, 0.0),
        );
        let leaf = regions.get(tall).unwrap();
        assert!(leaf.max_height >= 130.0 && leaf.max_height <= 130.1);
        assert!(leaf.east > tall.bounds(&root)[2] + 9.0 / 73_000.0);
        let root_region = regions
            .get(ImplicitTile {
                level: 0,
                x: 0,
                y: 0,
            })
            .unwrap();
        assert!(root_region.max_height >= 130.0 && root_region.min_height <= 90.0);
        assert_eq!(regions.all().count(), 1 + 4 + 16);
        // The parent of the tall leaf holds it; its sibling parent does not reach as high.
        let parent = regions
            .get(ImplicitTile {
                level: 1,
                x: 0,
                y: 1,
            })
            .unwrap();
        assert!(parent.max_height >= 130.0);
        let other = regions
            .get(ImplicitTile {
                level: 1,
                x: 1,
                y: 0,
            })
            .unwrap();
        assert!(other.max_height < 101.0);
        // Errors: 0 at the leaves, then each level's own (and at least its children's).
        assert_eq!(regions.error(tall), Some(0.0));
        assert_eq!(
            regions.error(ImplicitTile {
                level: 1,
                x: 1,
                y: 1
            }),
            Some(2.0)
        );
        assert_eq!(
            regions.error(ImplicitTile {
                level: 0,
                x: 0,
                y: 0
            }),
            Some(4.0)
        );
    }
}

//! The tileset JSON of a region with implicit quadtree tiling.

use super::regions::TileRegions;
use super::subtree::{TILE_CLASS, TILE_ERROR_PROPERTY, TILE_REGION_PROPERTY};
use crate::building::feature::BUILDING_CLASS;
use crate::geo::{GeoBbox, ImplicitTile, LocalFrame};
use serde_json::{Value, json};

/// The shape of the implicit tree over a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitLayout {
    pub root: GeoBbox,
    /// The level content is at (the deepest).
    pub leaf_level: u8,
    /// Heights of the region's bounding volume (metres).
    pub min_height: f64,
    pub max_height: f64,
    /// The root tile's geometric error (metres): what its coarse content does not draw.
    pub root_error: f64,
}

impl ImplicitLayout {
    /// The tree over `root` with the height range its content spans (the root tile's measured
    /// region).
    pub fn from_regions(root: GeoBbox, regions: &TileRegions) -> Self {
        let whole = regions.get(ImplicitTile {
            level: 0,
            x: 0,
            y: 0,
        });
        let (lo, hi) = whole.map_or((0.0, 0.0), |r| (r.min_height, r.max_height));
        let root_error = regions
            .error(ImplicitTile {
                level: 0,
                x: 0,
                y: 0,
            })
            .unwrap_or(0.0);
        Self {
            root,
            leaf_level: regions.leaf_level,
            min_height: lo,
            max_height: hi,
            root_error,
        }
    }

    /// The level whose tiles are at most [`LEAF_SIZE_M`] wide: it depends on the region alone.
    pub fn leaf_level_of(root: &GeoBbox) -> u8 {
        ImplicitTile::leaf_level(root)
    }

    pub fn available_levels(&self) -> u8 {
        self.leaf_level + 1
    }

    /// The geometric error the tileset gives its root: four times the region's diagonal, so
    /// that clients always refine into the tree, where each tile's own error (subtree metadata,
    /// `TILE_GEOMETRIC_ERROR`) decides. CesiumJS does not draw an implicit tree whose root it
    /// does not refine; 3d-tiles-renderer, which ignores the metadata, halves this per level
    /// and so refines to the leaves whenever the region is in view.
    pub fn tileset_root_error(&self) -> f64 {
        let (lon, lat) = self.root.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        let w = (self.root.max_lon() - self.root.min_lon()) * mx;
        let h = (self.root.max_lat() - self.root.min_lat()) * my;
        (4.0 * w.hypot(h)).max(self.root_error)
    }
}

/// The implicit tileset's schema: the buildings' class (the content's property tables) and the
/// class of the subtree's tile metadata, each tile's bounding region and geometric error.
fn implicit_schema() -> Value {
    let mut schema = BUILDING_CLASS.schema();
    schema["id"] = json!("citymesh_tileset");
    schema["classes"][TILE_CLASS] = json!({
        "description": "A tile of the implicit tree",
        "properties": {
            TILE_REGION_PROPERTY: {
                "description": "The tile's bounding region, measured on its content (radians, metres)",
                "type": "SCALAR",
                "componentType": "FLOAT64",
                "array": true,
                "count": 6,
                "semantic": "TILE_BOUNDING_REGION",
            },
            TILE_ERROR_PROPERTY: {
                "description": "The largest height the tile's level of detail does not draw (metres; 0 at the leaves)",
                "type": "SCALAR",
                "componentType": "FLOAT64",
                "semantic": "TILE_GEOMETRIC_ERROR",
            },
        },
    });
    schema
}

/// How the tileset lists its tiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tiling {
    /// Every tile written out with its measured bounding region and geometric error: every 3D
    /// Tiles client honours them (3d-tiles-renderer reads no subtree metadata).
    #[default]
    Explicit,
    /// A quadtree the client derives, with one binary subtree whose tile metadata
    /// (`TILE_BOUNDING_REGION`, `TILE_GEOMETRIC_ERROR`) holds the measured regions and errors
    /// (CesiumJS reads them).
    Implicit,
}

/// The tileset of the tree over `root` whose tiles' regions and errors are `regions`. `prefix`
/// is put before the content and subtree paths (relative URIs); `query`, when not empty, is
/// put after each content and subtree URI. It declares the schema of the buildings' property tables in its
/// content.
pub fn tileset_json(
    root: GeoBbox,
    regions: &TileRegions,
    tiling: Tiling,
    prefix: &str,
    query: &str,
) -> Value {
    let layout = ImplicitLayout::from_regions(root, regions);
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{query}")
    };
    let (schema, tree) = match tiling {
        Tiling::Explicit => {
            let mut schema = BUILDING_CLASS.schema();
            schema["id"] = json!("citymesh_tileset");
            let content =
                |t: ImplicitTile| format!("{prefix}content/{}/{}/{}.glb{query}", t.level, t.x, t.y);
            let mut tree = explicit_tile(
                regions,
                ImplicitTile {
                    level: 0,
                    x: 0,
                    y: 0,
                },
                &content,
            );
            tree["refine"] = json!("REPLACE");
            (schema, tree)
        }
        Tiling::Implicit => (
            implicit_schema(),
            json!({
                "boundingVolume": {"region": root_region(&layout)},
                "refine": "REPLACE",
                "geometricError": layout.tileset_root_error(),
                "content": {"uri": format!("{prefix}content/{{level}}/{{x}}/{{y}}.glb{query}")},
                "implicitTiling": {
                    "subdivisionScheme": "QUADTREE",
                    "availableLevels": layout.available_levels(),
                    "subtreeLevels": layout.available_levels(),
                    "subtrees": {"uri": format!("{prefix}subtrees/{{level}}/{{x}}/{{y}}.subtree{query}")}
                }
            }),
        ),
    };
    json!({
        "asset": {"version": "1.1", "generator": concat!("citymesh ", env!("CARGO_PKG_VERSION"))},
        "schema": schema,
        "geometricError": layout.tileset_root_error() * 2.0,
        "root": tree,
    })
}

/// The region of the whole tree: the tree's square at the heights its content spans.
fn root_region(layout: &ImplicitLayout) -> [f64; 6] {
    let r = &layout.root;
    [
        r.min_lon().to_radians(),
        r.min_lat().to_radians(),
        r.max_lon().to_radians(),
        r.max_lat().to_radians(),
        layout.min_height,
        layout.max_height,
    ]
}

/// Tile `t` of an explicit tree and, above the leaves, its four children: each with its
/// measured region and geometric error, and its content.
fn explicit_tile(
    regions: &TileRegions,
    t: ImplicitTile,
    content: &dyn Fn(ImplicitTile) -> String,
) -> Value {
    let region = regions.get(t).map(|r| r.to_radians()).unwrap_or_default();
    let mut tile = json!({
        "boundingVolume": {"region": region},
        "geometricError": regions.error(t).unwrap_or(0.0),
        "content": {"uri": content(t)},
    });
    if t.level < regions.leaf_level {
        let children: Vec<Value> = [(0, 0), (1, 0), (0, 1), (1, 1)]
            .into_iter()
            .map(|(dx, dy)| {
                let child = ImplicitTile {
                    level: t.level + 1,
                    x: 2 * t.x + dx,
                    y: 2 * t.y + dy,
                };
                explicit_tile(regions, child, content)
            })
            .collect();
        tile["children"] = children.into();
    }
    tile
}

//! The 3D Tiles answers that are not meshes: the regions of the tree's tiles over a region (for
//! the tileset) and its binary subtree. Content tiles go through [`super::generate`].

use super::limits::{run_blocking, within_timeout};
use crate::error::AppError;
use crate::state::AppState;
use bytes::Bytes;
use citymesh_core::building::roof::RoofShape;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::GeoBbox;
use citymesh_core::scene::RoofChoice;
use citymesh_core::tiles3d::{ImplicitLayout, TileRegions, measure_regions, root_subtree};
use std::sync::Arc;

/// The binary subtree at the root of the tree over `root` (the tree's only one): every tile
/// exists, every leaf has content (ground where it holds no building), and each tile's region
/// is its tile metadata.
pub async fn subtree(state: &AppState, root: GeoBbox, pitched: bool) -> Result<Bytes, AppError> {
    let regions = tile_regions(state, root, pitched).await?;
    Ok(Bytes::from(root_subtree(&regions)))
}

/// The region of every tile of the tree over `root`, measured on its content (kept per region,
/// as measuring generates the whole tree). With `pitched` (content with `roofs=classified` or
/// `roofs=inferred`), untagged roofs may become gabled or hipped: the regions hold those roofs
/// too.
pub async fn tile_regions(
    state: &AppState,
    root: GeoBbox,
    pitched: bool,
) -> Result<Arc<TileRegions>, AppError> {
    let key = (root.to_string(), pitched);
    state
        .tiles
        .regions
        .get_or_make(key, async {
            within_timeout(state, async {
                let buildings = state.source.buildings(&root).await?;
                let dem = state.dem.clone();
                let rules = citymesh_core::building::BuildingRules {
                    heights: state.height_base,
                    roof_method: state.roof_method,
                };
                run_blocking(state, move || {
                    let variants = if pitched {
                        roof_variants(&buildings.set)
                    } else {
                        Vec::new()
                    };
                    let regions = measure_regions(
                        &root,
                        ImplicitLayout::leaf_level_of(&root),
                        &buildings.set,
                        &|b| dem.lookup(b).model,
                        &variants,
                        rules,
                        &|| false,
                    )
                    .ok_or_else(|| AppError::internal("measuring the tiles stopped"))?;
                    Ok(Arc::new(regions))
                })
                .await
            })
            .await
        })
        .await
}

/// Every untagged roof as each pitched shape the classifier can choose.
fn roof_variants(set: &BuildingSet) -> Vec<RoofChoice> {
    [RoofShape::Gabled, RoofShape::Hipped]
        .into_iter()
        .map(|shape| {
            let mut choice = RoofChoice::new();
            for record in set.records() {
                if !record.tags.contains_key("roof:shape") {
                    choice.insert(record.id, shape, 1.0);
                }
            }
            choice
        })
        .collect()
}

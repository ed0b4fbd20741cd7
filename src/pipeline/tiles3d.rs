//! The 3D Tiles answers that are not meshes: the tree's layout over a region (for the tileset)
//! and its binary subtree. Content tiles go through [`super::generate`].

use super::limits::{run_blocking, within_timeout};
use crate::error::AppError;
use crate::state::AppState;
use citymesh_core::geo::GeoBbox;
use citymesh_core::tiles3d::{ImplicitLayout, root_subtree};

/// The tree over `root`, with its height range from the DEM and the tallest building.
pub async fn tileset_layout(state: &AppState, root: GeoBbox) -> Result<ImplicitLayout, AppError> {
    within_timeout(state, async {
        let buildings = state.source.buildings(&root).await?;
        let dem = state.dem.clone();
        run_blocking(state, move || {
            let model = dem.lookup(&root).model;
            Ok(ImplicitLayout::measure(root, &model, &buildings.set))
        })
        .await
    })
    .await
}

/// The binary subtree at the root of the tree over `root` (the tree's only one): every tile
/// exists, every leaf has content (ground where it holds no building).
pub async fn subtree(state: &AppState, root: GeoBbox) -> Result<Vec<u8>, AppError> {
    run_blocking(state, move || {
        Ok(root_subtree(ImplicitLayout::leaf_level_of(&root)))
    })
    .await
}

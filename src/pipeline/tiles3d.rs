//! The 3D Tiles answers that are not meshes: the regions of the tree's tiles over a region (for
//! the tileset) and its binary subtree. Content tiles go through [`super::generate`].

use super::limits::{generation_slot, within_timeout};
use super::{Generator, PipelineError};
use crate::cache::{RegionCache, Stopped};
use crate::error::AppError;
use bytes::Bytes;
use citymesh_core::building::roof::RoofShape;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::GeoBbox;
use citymesh_core::scene::RoofChoice;
use citymesh_core::tiles3d::{ImplicitLayout, TileRegions, measure_regions, root_subtree};
use std::sync::Arc;
use tokio_util::sync::CancellationToken;

/// The binary subtree at the root of the tree over `root` (the tree's only one): every tile
/// exists, every leaf has content (ground where it holds no building), and each tile's region
/// is its tile metadata.
pub async fn subtree(
    generator: &Generator,
    kept: &RegionCache<AppError>,
    root: GeoBbox,
    pitched: bool,
) -> Result<Bytes, AppError> {
    let regions = tile_regions(generator, kept, root, pitched).await?;
    Ok(Bytes::from(root_subtree(&regions)))
}

/// The region of every tile of the tree over `root`, measured on its content (kept per region in
/// `kept`, as measuring generates the whole tree). With `pitched` (content with `roofs=classified` or
/// `roofs=inferred`), untagged roofs may become gabled or hipped: the regions hold those roofs
/// too.
pub async fn tile_regions(
    generator: &Generator,
    kept: &RegionCache<AppError>,
    root: GeoBbox,
    pitched: bool,
) -> Result<Arc<TileRegions>, AppError> {
    let key = (root.to_string(), pitched);
    let max_work = generator
        .limits
        .request_timeout
        .saturating_mul(MEASURE_TIMEOUTS);
    let measure = |stop: CancellationToken| {
        let generator = generator.clone();
        async move {
            let buildings = generator.source.buildings(&root).await?;
            let dem = generator.dem.clone();
            let rules = citymesh_core::building::BuildingRules {
                heights: generator.height_base,
                roof_method: generator.roof_method,
            };
            let slot = generation_slot(&generator).await?;
            tokio::task::spawn_blocking(move || {
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
                    &|| stop.is_cancelled(),
                );
                drop(slot);
                regions
                    .map(Arc::new)
                    .ok_or_else(|| AppError::internal("measuring the tiles stopped"))
            })
            .await?
        }
    };
    // The request waits at most its timeout; the measurement goes on (and is kept) without it.
    within_timeout(
        generator,
        kept.get_or_measure(key, measure, &generator.stopping, max_work, measure_stopped),
    )
    .await
}

/// How many request timeouts a tree's measurement may take, with or without a client waiting:
/// long enough that a client retrying after a 503 `timeout` is answered from the kept regions,
/// short enough that abandoned work is bounded.
pub const MEASURE_TIMEOUTS: u32 = 4;

/// A measurement that stopped, as the client sees it.
fn measure_stopped(why: Stopped) -> AppError {
    match why {
        Stopped::Shutdown => PipelineError::ShuttingDown.into(),
        Stopped::TooLong(limit) => PipelineError::MeasureTooLong {
            limit,
            timeouts: MEASURE_TIMEOUTS,
        }
        .into(),
    }
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

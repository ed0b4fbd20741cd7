//! The crop of one footprint from an imagery service: the zoom its crop needs, the tiles under it
//! (each fetched once per round through the caller's `tiles` map, all of a round's at once with
//! [`prefetch_tiles`]), stitched and cut by the crop rule.

use super::{Imagery, ImageryError};
use citymesh_core::geo::TileCoord;
use citymesh_core::roof_image::CropRule;
use citymesh_core::roof_image::mosaic::FootprintCrop;
use citymesh_core::roof_image::{Crop, Image};
use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::sync::Arc;

/// Most imagery tiles one building's crop may need (a 3 x 3 block).
pub const MAX_TILES_PER_BUILDING: u64 = 9;

/// Tiles fetched so far, with their outcome.
pub type TileMemo = HashMap<TileCoord, Result<Arc<Image>, ImageryError>>;

/// Why a footprint has no crop, and whether trying later may help.
#[derive(Debug, Clone, PartialEq)]
pub struct CropFailure {
    /// `too_small: ...`, `too_large: ...` or `no_imagery: ...`.
    pub reason: String,
    pub retry: bool,
}

/// Tiles fetched at once by [`prefetch_tiles`]; the imagery source's own cap
/// (`--imagery-concurrency`) bounds what is in flight upstream.
const PREFETCH_AT_ONCE: usize = 16;

/// The tiles a footprint's crop needs, or `None` when it has no crop (the crop says why).
fn tiles_needed(footprint: &[[f64; 2]], imagery: &Imagery) -> Option<Vec<TileCoord>> {
    let spec = imagery.spec();
    let crop = FootprintCrop::new(footprint, CropRule::MODEL)?;
    let range = crop.tiles(crop.zoom(spec.tile_size, spec.max_zoom))?;
    (range.len() <= MAX_TILES_PER_BUILDING).then(|| range.tiles().collect())
}

/// Fetches every tile the footprints' crops need and `tiles` lacks, concurrently (each once),
/// so a round on slow imagery takes about as long as its slowest tiles, not their sum.
pub async fn prefetch_tiles(footprints: &[&[[f64; 2]]], imagery: &Imagery, tiles: &mut TileMemo) {
    use futures_util::StreamExt;
    let mut wanted: Vec<TileCoord> = footprints
        .iter()
        .filter_map(|f| tiles_needed(f, imagery))
        .flatten()
        .filter(|t| !tiles.contains_key(t))
        .collect();
    wanted.sort_unstable();
    wanted.dedup();
    let fetched: Vec<(TileCoord, Result<Arc<Image>, ImageryError>)> =
        futures_util::stream::iter(wanted)
            .map(|t| async move { (t, imagery.tile(t).await.map(Arc::new)) })
            .buffer_unordered(PREFETCH_AT_ONCE)
            .collect()
            .await;
    for (t, result) in fetched {
        if let Err(e) = &result {
            tracing::warn!(tile = ?t, error = %e, "imagery tile failed");
        }
        tiles.insert(t, result);
    }
}

/// The crop of a footprint (outer ring, lon/lat).
pub async fn crop_footprint(
    footprint: &[[f64; 2]],
    imagery: &Imagery,
    tiles: &mut TileMemo,
) -> Result<Crop, CropFailure> {
    let fail = |reason: String, retry| CropFailure { reason, retry };
    let spec = imagery.spec();
    let crop = FootprintCrop::new(footprint, CropRule::MODEL)
        .ok_or_else(|| fail("too_small: the footprint has no extent".into(), false))?;
    let zoom = crop.zoom(spec.tile_size, spec.max_zoom);
    let range = crop
        .tiles(zoom)
        .ok_or_else(|| fail("too_small: no crop area".into(), false))?;
    if range.len() > MAX_TILES_PER_BUILDING {
        return Err(fail(
            format!("too_large: needs {} imagery tiles", range.len()),
            false,
        ));
    }
    let mut got: Vec<(TileCoord, Arc<Image>)> = Vec::new();
    for t in range.tiles() {
        if let Entry::Vacant(slot) = tiles.entry(t) {
            let fetched = imagery.tile(t).await.map(Arc::new);
            if let Err(e) = &fetched {
                tracing::warn!(tile = ?t, error = %e, "imagery tile failed");
            }
            slot.insert(fetched);
        }
        match tiles.get(&t) {
            Some(Ok(image)) => got.push((t, image.clone())),
            Some(Err(e)) => {
                return Err(fail(format!("no_imagery: {e}"), e.may_pass()));
            }
            None => return Err(fail("no_imagery".into(), true)),
        }
    }
    let refs: Vec<(TileCoord, &Image)> = got.iter().map(|(t, i)| (*t, i.as_ref())).collect();
    Ok(crop.crop(&range, spec.tile_size as usize, &refs))
}

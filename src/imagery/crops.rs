//! The crop of one footprint from an imagery service: the zoom its crop needs, the tiles under it
//! (each fetched once per round through the caller's `tiles` map), stitched and cut by the crop
//! rule.

use super::{Imagery, ImageryError};
use crate::classifier::MODEL_RULE;
use citymesh_core::geo::TileCoord;
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

/// The crop of a footprint (outer ring, lon/lat).
pub async fn crop_footprint(
    footprint: &[[f64; 2]],
    imagery: &Imagery,
    tiles: &mut TileMemo,
) -> Result<Crop, CropFailure> {
    let fail = |reason: String, retry| CropFailure { reason, retry };
    let spec = imagery.spec();
    let crop = FootprintCrop::new(footprint, MODEL_RULE)
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

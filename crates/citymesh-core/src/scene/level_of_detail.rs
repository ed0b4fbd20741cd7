//! Coarser content for the coarser levels of the 3D Tiles tree. Above the leaves, a tile holds
//! every group its square holds, simplified by one rule:
//!
//! - every building and part is kept, so a block of small houses is still a block from afar
//!   (leaving the small ones out emptied whole districts at the distance a client draws the
//!   coarse levels from);
//! - a roof is flattened at its mean height, halfway between eaves and top;
//! - the ground is a 16 x 16 grid over the tile (the leaves keep every DEM cell).
//!
//! Its geometric error is the largest height a client does not see at that level: half a
//! flattened roof's, or the coarse ground's distance from the model at its cells' centres.

use crate::building::RoofMethod;
use crate::building::generate::{RecordOutline, record_outline};
use crate::geo::{GeoBbox, LocalFrame};
use crate::osm::BuildingRecord;
use crate::terrain::ElevationModel;
use std::borrow::Cow;

/// How coarse a tile's content is: levels above the leaves (0: the leaves, full detail).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct LevelOfDetail {
    pub above_leaves: u8,
    /// Above the leaves, keep the DEM's ground (the world tree's tiles of buildings, whose
    /// ground is about as fine as the DEM) rather than the coarse grid.
    pub dem_ground: bool,
}

/// What simplifying a record did, for the level's geometric error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Simplified {
    /// Drawn as it is (a flat roof).
    Kept,
    /// Its roof flattened: half its rise is not drawn.
    Flattened { hidden_m: f64 },
}

impl LevelOfDetail {
    /// Cells per side of a coarse tile's ground grid.
    pub const GROUND_CELLS: u32 = 16;

    pub fn is_full(self) -> bool {
        self.above_leaves == 0
    }

    /// Whether the ground is the coarse grid rather than the DEM's.
    pub fn grid_ground(self) -> bool {
        !self.is_full() && !self.dem_ground
    }

    /// The record as this level draws it, and what that hides.
    pub fn simplify<'a>(
        self,
        record: Cow<'a, BuildingRecord>,
        frame: &LocalFrame,
        roof_method: RoofMethod,
    ) -> (Cow<'a, BuildingRecord>, Simplified) {
        if self.is_full() {
            return (record, Simplified::Kept);
        }
        let Some(RecordOutline {
            height,
            min_height,
            roof_height,
            ..
        }) = record_outline(&record, frame, roof_method)
        else {
            // The generator will skip it and say why.
            return (record, Simplified::Kept);
        };
        if roof_height <= 0.0 {
            return (record, Simplified::Kept);
        }
        let mut flat = record.into_owned();
        let mean = height - roof_height / 2.0;
        flat.tags.insert("roof:shape".into(), "flat".into());
        flat.tags.insert("height".into(), format!("{mean:.3}"));
        flat.tags
            .insert("min_height".into(), format!("{min_height:.3}"));
        (
            Cow::Owned(flat),
            Simplified::Flattened {
                hidden_m: roof_height / 2.0,
            },
        )
    }

    /// How far the coarse ground grid of `bbox` lies from the model at its cells' centres (m).
    pub fn ground_error(bbox: &GeoBbox, model: &ElevationModel) -> f64 {
        let n = f64::from(Self::GROUND_CELLS);
        let (dx, dy) = (
            (bbox.max_lon() - bbox.min_lon()) / n,
            (bbox.max_lat() - bbox.min_lat()) / n,
        );
        let h =
            |i: f64, j: f64| model.ground_height(bbox.min_lon() + dx * i, bbox.min_lat() + dy * j);
        let mut worst = 0.0f64;
        for j in 0..Self::GROUND_CELLS {
            for i in 0..Self::GROUND_CELLS {
                let (i, j) = (f64::from(i), f64::from(j));
                let corners = (h(i, j) + h(i + 1.0, j) + h(i + 1.0, j + 1.0) + h(i, j + 1.0)) / 4.0;
                worst = worst.max((h(i + 0.5, j + 0.5) - corners).abs());
            }
        }
        worst
    }
}

//! SRTM terrain: HGT files parsed from bytes ([`HgtTile`]), the samples of any number of them
//! seen as one seamless grid ([`ElevationModel`]), the elevation of any point (Equation 1), and
//! the ground mesh of a bounding box ([`build_ground`]).
//!
//! Finding and reading files is the caller's job; this module only ever sees bytes.

mod coarse_ground;
mod elevation;
mod ground;
mod hgt;
mod model;
mod range;

pub use coarse_ground::{CellMask, build_coarse_ground};
pub use elevation::corner_height;
pub use ground::{GroundReport, build_ground};
pub use hgt::{HgtError, HgtTile, VOID, hgt_name, parse_hgt_name};
pub use model::{ElevationModel, Sample, dem_tiles_for};

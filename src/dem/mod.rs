//! The DEM store: finds SRTM files in a directory, reads them (plain, gzip or zip) when an area
//! first needs them, and keeps the parsed tiles in a bounded memory cache. Parsing itself is the
//! core's job (`citymesh_core::terrain`).

mod files;
mod store;

pub use files::{DemFileError, read_hgt};
pub use store::{DemLookup, DemStore};

//! OpenStreetMap data for the generator: the files given with `--osm` (PBF, OSM XML or Overpass
//! JSON, each optionally gzipped), or data tiles of one fixed zoom kept in SQLite and filled from
//! Overpass or by `citymesh import`. Parsing and indexing are the core's job
//! (`citymesh_core::osm`, `citymesh_core::building::set`).

pub mod data_tile;
mod files;
pub mod import;
mod source;
mod store;

pub use files::{OsmData, OsmFileError, load_osm_files, read_osm_file};
pub use source::{AreaBuildings, DataTileSource, OsmSource};
pub use store::{DataSource, OsmTileStore, StoredDataTile, content_hash};

//! Local OpenStreetMap data: the files given with `--osm` (PBF, OSM XML or Overpass JSON, each
//! optionally gzipped) read at start-up into one indexed building set. Parsing and indexing are
//! the core's job (`citymesh_core::osm`, `citymesh_core::building::set`).

mod files;

pub use files::{OsmData, OsmFileError, load_osm_files};

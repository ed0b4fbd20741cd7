//! GeoJSON for building definitions: procedural cities are written as a FeatureCollection with
//! OSM-style properties, and user-written collections (Polygon and MultiPolygon features, holes
//! allowed) are read and checked into the same building records OSM input produces.

mod read;
mod write;

pub use read::{GeoJsonError, GeoJsonErrorKind, GeoJsonLimits, GeoJsonScene, read_geojson};
pub use write::write_geojson;

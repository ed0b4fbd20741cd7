//! citymesh-core: the pure, synchronous and deterministic core of citymesh.
//!
//! It owns geometry and formats: geographic frames and tile math ([`geo`]), SRTM terrain and the
//! ground grid ([`terrain`]), OSM input ([`osm`]), buildings and their roofs ([`building`]),
//! procedural cities ([`procedural`]), GeoJSON building definitions ([`geojson`]), scenes
//! ([`scene`]), small learners fitted at run time ([`learn`]), the roof prior learned from an area's tags
//! ([`roof_prior`]), and the mesh type with its
//! glTF/GLB writer ([`mesh`]). It performs no I/O: callers hand it bytes and receive bytes. Nothing here knows about HTTP, files or async.

pub mod building;
pub mod geo;
pub mod geojson;
pub mod learn;
pub mod mesh;
pub mod osm;
pub mod procedural;
pub mod roof_image;
pub mod roof_prior;
pub mod scene;
pub mod terrain;
pub mod tiles3d;
mod union_find;

//! citymesh: an HTTP server that turns OpenStreetMap buildings and SRTM terrain into 3D city
//! meshes on demand.
//!
//! The geometry lives in the pure `citymesh-core` crate; this crate is everything around it: the
//! command line ([`cli`]), the DEM file store ([`dem`]), local OSM data ([`osm`]), the SQLite cache
//! ([`db`]), the HTTP routes
//! ([`routes`]) and the server's lifecycle ([`server`]). A request flows one way:
//! route -> cache lookup -> data source -> core generator in `spawn_blocking` -> cache -> response.

pub mod cli;
pub mod db;
pub mod dem;
pub mod error;
pub mod generate;
pub mod metrics;
pub mod osm;
pub mod routes;
pub mod server;
pub mod state;
pub mod tile_cache;
pub mod upstream;

pub use error::AppError;
pub use routes::app;
pub use state::AppState;

//! citymesh: an HTTP server that turns OpenStreetMap buildings and SRTM terrain into 3D city
//! meshes on demand.
//!
//! The geometry lives in the pure `citymesh-core` crate; this crate is everything around it: the
//! command line ([`cli`]), the DEM file store ([`dem`]), the building sources ([`source`]), the
//! caches of generated content ([`cache`], stored through [`db`]), the request pipeline
//! ([`pipeline`]), the HTTP routes ([`routes`]) and the server's lifecycle ([`server`]). A request
//! flows one way: route -> cache -> source -> core (in `spawn_blocking`) -> cache -> response.
//! `docs/architecture.md` draws it.

pub mod cache;
pub mod cli;
pub mod clock;
pub mod commands;
pub mod db;
pub mod dem;
pub mod error;
pub mod generation_stats;
pub mod metrics;
pub mod pipeline;
pub mod roofs;
pub mod routes;
pub mod server;
pub mod source;
pub mod state;
pub mod upstream;

pub use error::AppError;
pub use routes::app;
pub use state::AppState;

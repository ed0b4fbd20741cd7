//! The request pipeline, between the routes and the core: gathers what an area needs (its
//! buildings from the source, the DEM files), waits for a generation slot, runs the core's
//! `SceneRequest` on the blocking pool under the request timeout ([`limits`]), and returns bytes
//! with their figures ([`scene`]); roofs chosen from the classifier's predictions or the roof
//! prior come from [`roofs`]; the 3D Tiles tree's layout and subtree come from here too
//! ([`tiles3d`]), and the world tileset's content ([`world`]). It knows nothing of HTTP headers (`crate::routes` formats them) or of caching
//! (the routes ask `crate::cache` first and hand this pipeline to it on a miss).

mod error;
mod generator;
mod limits;
mod roofs;
mod scene;
mod tiles3d;
pub mod world;

pub use crate::generation_stats::GenerationStats;
pub use error::PipelineError;
pub use generator::{Generator, GeneratorParts};
pub use limits::{run_blocking, within_timeout};
pub use roofs::{
    ClassifiedRoofs, InferredFigures, InferredRoofs, PriorFigures, RoofFigures, RoofsParam,
    classified_roofs, inferred_roofs,
};
pub use scene::{Buildings, Generated, MeshOptions, gather, generate};
pub use tiles3d::{subtree, tile_regions};

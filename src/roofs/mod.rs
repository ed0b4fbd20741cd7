//! Everything about roof shapes that the tags do not give (docs/extensions.md): the classifier
//! ([`classifier`]: the CNN, its input and its adapted heads), the imagery it reads
//! ([`imagery`]), the queued jobs that run it and their adaptations ([`jobs`]), and the roof
//! prior learned from an area's own tags ([`prior`]).
//!
//! The rest of the server uses one face: [`RoofJobs`] (queue, workers, predictions, the model in
//! use and adaptations), built once by the server from [`RoofJobsConfig`]; the routes of
//! `/classify` call it, and the pipeline reads predictions and priors through it. Within this
//! folder, imports go one way: `jobs` -> `classifier`, `imagery` -> the core.

pub mod classifier;
pub mod imagery;
pub mod jobs;
pub mod prior;

pub use classifier::RoofClassifier;
pub use imagery::{Imagery, ImagerySpec};
pub use jobs::{JobError, RoofJobs, RoofJobsConfig};

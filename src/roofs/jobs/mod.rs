//! Queued roof-classification jobs (docs/extensions.md section 1): batches of buildings to classify,
//! kept in the database so nothing is lost on a crash, claimed by workers under a lease so a
//! worker that dies leaves its jobs to another, and the predictions they store.
//!
//! [`JobQueue`] is the queue on the opened [`crate::db::Database`]: SQLite, or a PostgreSQL
//! server that many replicas share (claims take their rows with `FOR UPDATE SKIP LOCKED`). [`worker`] runs jobs: imagery, crop, inference, store. [`RoofJobs`] is the server's side:
//! the queue, the workers, and the [`PredictionIndex`] that `roofs=classified` tiles read.

pub mod adapt;
pub mod batch_budget;
mod index;
mod job;
mod prediction_note;
mod queue;
pub mod replica_predictions;
mod select;
mod service;
mod token;
pub mod worker;

pub use index::{IndexedPrediction, PredictionIndex};
pub use job::{
    BatchCounts, BatchProgress, ClaimedJob, JobError, MAX_ATTEMPTS, NewJob, StoredPrediction,
    footprint_hash, ring_bounds,
};
pub use queue::JobQueue;
pub use select::{Selection, jobs_in_box, select_buildings};
pub use service::{ActiveModel, RoofJobs, RoofJobsConfig};
pub use token::{is_token, random_token};

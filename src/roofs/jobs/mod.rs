//! Queued roof-classification jobs (docs/extensions.md section 1): batches of buildings to classify,
//! kept in the database so nothing is lost on a crash, claimed by workers under a lease so a
//! worker that dies leaves its jobs to another, and the predictions they store.
//!
//! [`RoofJobQueue`] is the queue's contract. [`SqliteJobQueue`] implements it on the cache
//! database, [`PgJobQueue`] on a PostgreSQL server that many replicas share (claims take their
//! rows with `FOR UPDATE SKIP LOCKED`); [`JobQueue`] is whichever the [`crate::db::Database`]
//! is. [`worker`] runs jobs: imagery, crop, inference, store. [`RoofJobs`] is the server's side:
//! the queue, the workers, and the [`PredictionIndex`] that `roofs=classified` tiles read.

pub mod adapt;
mod backend;
pub mod batch_budget;
mod index;
mod postgres;
mod prediction_note;
mod queue;
pub mod replica_predictions;
mod rows;
mod select;
mod service;
mod sqlite;
mod token;
pub mod worker;

pub use backend::JobQueue;
pub use index::{IndexedPrediction, PredictionIndex};
pub use postgres::PgJobQueue;
pub use queue::{
    BatchCounts, BatchProgress, ClaimedJob, JobError, MAX_ATTEMPTS, NewJob, RoofJobQueue,
    StoredPrediction, footprint_hash, ring_bounds,
};
pub use select::{Selection, jobs_in_box, select_buildings};
pub use service::{ActiveModel, RoofJobs, RoofJobsConfig};
pub use sqlite::SqliteJobQueue;
pub use token::{is_token, random_token};

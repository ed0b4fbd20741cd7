//! The queue on whichever database the server was opened on.

use super::postgres::PgJobQueue;
use super::queue::{
    BatchCounts, BatchProgress, ClaimedJob, JobError, NewJob, RoofJobQueue, StoredPrediction,
};
use super::sqlite::SqliteJobQueue;
use crate::db::Database;
use crate::roofs::classifier::Prediction;
use citymesh_core::geo::GeoBbox;
use std::collections::BTreeMap;
use std::time::Duration;

/// [`RoofJobQueue`] on the [`Database`] it was made for.
#[derive(Clone)]
pub enum JobQueue {
    Sqlite(SqliteJobQueue),
    Postgres(PgJobQueue),
}

/// Runs `$call` on the queue of whichever backend `$queue` is.
macro_rules! delegate {
    ($queue:expr, $q:ident => $call:expr) => {
        match $queue {
            JobQueue::Sqlite($q) => $call,
            JobQueue::Postgres($q) => $call,
        }
    };
}

impl JobQueue {
    pub fn new(db: &Database) -> Self {
        match db {
            Database::Sqlite(pool) => Self::Sqlite(SqliteJobQueue::new(pool.clone())),
            Database::Postgres(pool) => Self::Postgres(PgJobQueue::new(pool.clone())),
        }
    }

    /// The database the queue lives in (the adaptations live there too).
    pub fn database(&self) -> Database {
        match self {
            Self::Sqlite(q) => Database::Sqlite(q.pool().clone()),
            Self::Postgres(q) => Database::Postgres(q.pool().clone()),
        }
    }
}

impl RoofJobQueue for JobQueue {
    async fn enqueue(
        &self,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        jobs: &[NewJob],
        skipped: BTreeMap<String, u64>,
    ) -> Result<(String, BatchCounts), JobError> {
        delegate!(self, q => q.enqueue(bbox, imagery_id, model_id, jobs, skipped).await)
    }

    async fn claim(&self, n: u32, lease: Duration) -> Result<Vec<ClaimedJob>, JobError> {
        delegate!(self, q => q.claim(n, lease).await)
    }

    async fn extend(&self, claim: i64, lease: Duration) -> Result<u64, JobError> {
        delegate!(self, q => q.extend(claim, lease).await)
    }

    async fn complete(
        &self,
        job: &ClaimedJob,
        prediction: Prediction,
        work_ms: f64,
    ) -> Result<bool, JobError> {
        delegate!(self, q => q.complete(job, prediction, work_ms).await)
    }

    async fn states(&self) -> Result<BTreeMap<String, u64>, JobError> {
        delegate!(self, q => q.states().await)
    }

    async fn fail(&self, job: &ClaimedJob, reason: &str, retry: bool) -> Result<bool, JobError> {
        delegate!(self, q => q.fail(job, reason, retry).await)
    }

    async fn progress(&self, batch: &str) -> Result<Option<BatchProgress>, JobError> {
        delegate!(self, q => q.progress(batch).await)
    }

    async fn cancel(&self, batch: &str) -> Result<Option<u64>, JobError> {
        delegate!(self, q => q.cancel(batch).await)
    }

    async fn predictions_of(
        &self,
        imagery_id: &str,
        model_id: &str,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        delegate!(self, q => q.predictions_of(imagery_id, model_id).await)
    }

    async fn predictions(
        &self,
        bbox: &GeoBbox,
        limit: u32,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        delegate!(self, q => q.predictions(bbox, limit).await)
    }
}

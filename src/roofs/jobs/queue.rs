//! What a roof job queue does, whatever stores it.

use crate::roofs::classifier::Prediction;
use citymesh_core::geo::GeoBbox;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Duration;

/// Attempts a job gets before it is failed for good.
pub const MAX_ATTEMPTS: i64 = 3;

/// A building to classify.
#[derive(Debug, Clone, PartialEq)]
pub struct NewJob {
    /// `way/123` or `relation/45`.
    pub osm_id: String,
    /// The outer ring, lon/lat.
    pub footprint: Vec<[f64; 2]>,
}

/// The xxh3 of a footprint's coordinates (to 1e-7 degrees), hex: a changed outline is a new job.
pub fn footprint_hash(footprint: &[[f64; 2]]) -> String {
    let mut text = String::with_capacity(footprint.len() * 24);
    for p in footprint {
        text.push_str(&format!("{:.7},{:.7};", p[0], p[1]));
    }
    format!("{:016x}", xxhash_rust::xxh3::xxh3_64(text.as_bytes()))
}

/// The box of lon/lat points: `[west, south, east, north]`, `None` without points.
pub fn ring_bounds<'a>(points: impl IntoIterator<Item = &'a [f64; 2]>) -> Option<[f64; 4]> {
    let mut points = points.into_iter();
    let first = points.next()?;
    let mut b = [first[0], first[1], first[0], first[1]];
    for p in points {
        b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    Some(b)
}

/// A batch as made: jobs queued, buildings already queued or classified, and skipped ones.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct BatchCounts {
    /// New jobs queued by this batch.
    pub queued: u64,
    /// Buildings with a job already (queued, running or done) for the same inputs.
    pub already: u64,
    /// Buildings not queued, by reason (`tagged`, `has_parts`, `too_small`, `part`).
    pub skipped: BTreeMap<String, u64>,
}

/// Where a batch stands.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct BatchProgress {
    /// The batch's token (32 hex digits).
    pub id: String,
    pub bbox: String,
    pub imagery_id: String,
    pub model_id: String,
    pub counts: BatchCounts,
    /// This batch's jobs by state: queued, running, done, failed, cancelled.
    pub jobs: BTreeMap<String, u64>,
    /// No job of the batch is queued or running.
    pub finished: bool,
    pub cancelled: bool,
}

/// A job a worker holds under a lease.
#[derive(Debug, Clone, PartialEq)]
pub struct ClaimedJob {
    pub id: i64,
    pub osm_id: String,
    pub footprint_hash: String,
    pub imagery_id: String,
    pub model_id: String,
    pub footprint: Vec<[f64; 2]>,
    pub attempts: i64,
    /// The claim (random): every state change checks the job is still under it.
    pub claim: i64,
}

/// A stored prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredPrediction {
    pub osm_id: String,
    pub footprint_hash: String,
    pub imagery_id: String,
    pub model_id: String,
    pub prediction: Prediction,
    pub footprint: Vec<[f64; 2]>,
    /// Its share of its worker round's time, milliseconds.
    pub work_ms: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum JobError {
    #[error("job store: {0}")]
    Store(#[from] sqlx::Error),
    #[error("job store: a stored footprint is not valid JSON: {0}")]
    Corrupt(String),
}

/// The queue's contract.
pub trait RoofJobQueue: Send + Sync {
    /// Makes a batch and queues a job per building not yet queued or done for these inputs;
    /// answers the batch's token and counts.
    fn enqueue(
        &self,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        jobs: &[NewJob],
        skipped: BTreeMap<String, u64>,
    ) -> impl Future<Output = Result<(String, BatchCounts), JobError>> + Send;

    /// Claims up to `n` jobs (queued, or running with a lease run out) for `lease`.
    fn claim(
        &self,
        n: u32,
        lease: Duration,
    ) -> impl Future<Output = Result<Vec<ClaimedJob>, JobError>> + Send;

    /// Extends the lease of the claim's jobs still running under it to `lease` from now; answers
    /// how many it holds.
    fn extend(
        &self,
        claim: i64,
        lease: Duration,
    ) -> impl Future<Output = Result<u64, JobError>> + Send;

    /// Stores the prediction (which took `work_ms`) and marks the job done, in one transaction, if the job is still
    /// this claim's (running, under the same claim); `false` when its lease ran out and another
    /// claim took it, or it was cancelled: then nothing is stored, so a job is done exactly once.
    fn complete(
        &self,
        job: &ClaimedJob,
        prediction: Prediction,
        work_ms: f64,
    ) -> impl Future<Output = Result<bool, JobError>> + Send;

    /// Jobs by state, over every batch.
    fn states(&self) -> impl Future<Output = Result<BTreeMap<String, u64>, JobError>> + Send;

    /// Gives the job back for another attempt, or fails it for good after [`MAX_ATTEMPTS`] or when
    /// `retry` is false; `false` (and nothing changed) when the job is no longer this claim's.
    fn fail(
        &self,
        job: &ClaimedJob,
        reason: &str,
        retry: bool,
    ) -> impl Future<Output = Result<bool, JobError>> + Send;

    /// The batch's progress, `None` if there is no such batch.
    fn progress(
        &self,
        batch: &str,
    ) -> impl Future<Output = Result<Option<BatchProgress>, JobError>> + Send;

    /// Cancels the batch's queued jobs that no other live batch asked for; `None` if there is
    /// no such batch.
    fn cancel(&self, batch: &str) -> impl Future<Output = Result<Option<u64>, JobError>> + Send;

    /// Every prediction made from `imagery_id` by `model_id`.
    fn predictions_of(
        &self,
        imagery_id: &str,
        model_id: &str,
    ) -> impl Future<Output = Result<Vec<StoredPrediction>, JobError>> + Send;

    /// Predictions whose footprint's box meets `bbox`, at most `limit`.
    fn predictions(
        &self,
        bbox: &GeoBbox,
        limit: u32,
    ) -> impl Future<Output = Result<Vec<StoredPrediction>, JobError>> + Send;
}

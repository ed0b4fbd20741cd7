//! A roof job and what the queue answers about jobs: buildings to classify, claimed jobs, stored
//! predictions, batches and their progress.

use crate::roofs::classifier::Prediction;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

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

//! Claims, leases, rings as stored, and the rows the queue reads back (the same columns on both
//! backends).

use crate::roofs::classifier::Prediction;
use crate::roofs::jobs::job::{ClaimedJob, JobError, StoredPrediction};
use sqlx::{ColumnIndex, Decode, Row, Type};
use std::collections::BTreeMap;
use std::time::Duration;

/// Jobs upserted per transaction when a batch is queued.
pub(super) const ENQUEUE_CHUNK: usize = 256;

/// When a lease taken at `now` (ms) for `lease` ends.
pub(super) fn lease_end(now: i64, lease: Duration) -> i64 {
    now.saturating_add(i64::try_from(lease.as_millis()).unwrap_or(i64::MAX))
}

/// A random claim number.
pub(super) fn random_claim() -> Result<i64, JobError> {
    let mut bytes = [0u8; 8];
    getrandom::fill(&mut bytes).map_err(|e| JobError::Corrupt(format!("no randomness: {e}")))?;
    Ok(i64::from_le_bytes(bytes))
}

/// A ring as stored: JSON `[[lon, lat], ...]`.
pub(super) fn ring_json(ring: &[[f64; 2]]) -> String {
    serde_json::to_string(ring).unwrap_or_else(|_| "[]".into())
}

pub(super) fn parse_ring(text: &str) -> Result<Vec<[f64; 2]>, JobError> {
    serde_json::from_str(text).map_err(|e| JobError::Corrupt(e.to_string()))
}

/// Every state at 0.
pub(super) fn empty_states() -> BTreeMap<String, u64> {
    ["queued", "running", "done", "failed", "cancelled"]
        .iter()
        .map(|s| ((*s).to_owned(), 0))
        .collect()
}

/// A claimed job from a row of `id, osm_id, footprint_hash, imagery_id, model_id, footprint,
/// attempts`.
pub(super) fn claimed_of_row<'r, R: Row>(r: &'r R, claim: i64) -> Result<ClaimedJob, JobError>
where
    usize: ColumnIndex<R>,
    i64: Decode<'r, R::Database> + Type<R::Database>,
    String: Decode<'r, R::Database> + Type<R::Database>,
{
    Ok(ClaimedJob {
        id: r.get(0),
        osm_id: r.get(1),
        footprint_hash: r.get(2),
        imagery_id: r.get(3),
        model_id: r.get(4),
        footprint: parse_ring(&r.get::<String, _>(5))?,
        attempts: r.get(6),
        claim,
    })
}

/// A stored prediction from a row of `prediction_columns!`.
pub(super) fn prediction_of_row<'r, R: Row>(r: &'r R) -> Result<StoredPrediction, JobError>
where
    usize: ColumnIndex<R>,
    f64: Decode<'r, R::Database> + Type<R::Database>,
    String: Decode<'r, R::Database> + Type<R::Database>,
{
    Ok(StoredPrediction {
        osm_id: r.get(0),
        footprint_hash: r.get(1),
        imagery_id: r.get(2),
        model_id: r.get(3),
        prediction: Prediction::new([
            r.get::<f64, _>(4) as f32,
            r.get::<f64, _>(5) as f32,
            r.get::<f64, _>(6) as f32,
        ]),
        footprint: parse_ring(&r.get::<String, _>(7))?,
        work_ms: r.get(8),
    })
}

//! The queue's statements, each written once for both backends (`$n` placeholders, which SQLite
//! takes too, and `ON CONFLICT`); [`Dialect`] holds the real differences: how a claim picks its
//! rows, how text is ordered, and what only PostgreSQL does for its replicas (an advisory lock
//! that serialises enqueues and cancellations, a notification per prediction).

/// The columns `prediction_of_row` reads.
macro_rules! prediction_columns {
    () => {
        "SELECT osm_id, footprint_hash, imagery_id, model_id, p_flat, p_gabled, p_hipped, \
         footprint, work_ms FROM roof_predictions"
    };
}

pub(super) const NEW_BATCH: &str = "INSERT INTO roof_batches (created_at, bbox, imagery_id, \
    model_id, counts, token) VALUES ($1, $2, $3, $4, '{}', $5) RETURNING id";

/// Queues a job; one that failed for good or was cancelled is queued again by a new batch.
pub(super) const UPSERT_JOB: &str = "INSERT INTO roof_jobs (batch_id, osm_id, footprint_hash, \
    imagery_id, model_id, footprint, state, updated_at) \
    VALUES ($1, $2, $3, $4, $5, $6, 'queued', $7) \
    ON CONFLICT (osm_id, footprint_hash, imagery_id, model_id) DO UPDATE SET \
    batch_id = excluded.batch_id, state = 'queued', attempts = 0, error = NULL, \
    lease_until = NULL, updated_at = excluded.updated_at \
    WHERE roof_jobs.state IN ('failed', 'cancelled')";

/// Makes the job the batch's too, whichever batch queued it.
pub(super) const LINK_JOB: &str = "INSERT INTO roof_batch_jobs (batch_id, job_id) SELECT $1, id \
    FROM roof_jobs WHERE osm_id = $2 AND footprint_hash = $3 AND imagery_id = $4 \
    AND model_id = $5 ON CONFLICT DO NOTHING";

pub(super) const BATCH_COUNTS: &str = "UPDATE roof_batches SET counts = $1 WHERE id = $2";

pub(super) const EXTEND: &str = "UPDATE roof_jobs SET lease_until = $1, updated_at = $2 \
    WHERE claim = $3 AND state = 'running'";

/// Marks the job done if it is still the claim's.
pub(super) const MARK_DONE: &str = "UPDATE roof_jobs SET state = 'done', lease_until = NULL, \
    error = NULL, updated_at = $1 WHERE id = $2 AND state = 'running' AND claim = $3";

pub(super) const UPSERT_PREDICTION: &str = "INSERT INTO roof_predictions (osm_id, \
    footprint_hash, imagery_id, model_id, p_flat, p_gabled, p_hipped, footprint, min_lon, \
    min_lat, max_lon, max_lat, created_at, work_ms) \
    VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14) \
    ON CONFLICT (osm_id, footprint_hash, imagery_id, model_id) DO UPDATE SET \
    p_flat = excluded.p_flat, p_gabled = excluded.p_gabled, p_hipped = excluded.p_hipped, \
    footprint = excluded.footprint, min_lon = excluded.min_lon, min_lat = excluded.min_lat, \
    max_lon = excluded.max_lon, max_lat = excluded.max_lat, created_at = excluded.created_at, \
    work_ms = excluded.work_ms";

pub(super) const STATES: &str = "SELECT state, COUNT(*) FROM roof_jobs GROUP BY state";

pub(super) const FAIL: &str = "UPDATE roof_jobs SET state = $1, lease_until = NULL, error = $2, \
    updated_at = $3 WHERE id = $4 AND state = 'running' AND claim = $5";

pub(super) const BATCH: &str = "SELECT bbox, imagery_id, model_id, counts, cancelled, id \
    FROM roof_batches WHERE token = $1";

pub(super) const BATCH_STATES: &str = "SELECT j.state, COUNT(*) FROM roof_batch_jobs b \
    JOIN roof_jobs j ON j.id = b.job_id WHERE b.batch_id = $1 GROUP BY j.state";

pub(super) const CANCEL_BATCH: &str =
    "UPDATE roof_batches SET cancelled = 1 WHERE token = $1 RETURNING id";

/// Cancels the batch's queued jobs that no other live batch asked for.
pub(super) const CANCEL_JOBS: &str = "UPDATE roof_jobs SET state = 'cancelled', updated_at = $1 \
    WHERE state = 'queued' AND id IN (SELECT job_id FROM roof_batch_jobs WHERE batch_id = $2) \
    AND NOT EXISTS (SELECT 1 FROM roof_batch_jobs o JOIN roof_batches b ON b.id = o.batch_id \
    WHERE o.job_id = roof_jobs.id AND o.batch_id <> $2 AND b.cancelled = 0)";

/// The transaction-scoped advisory lock (`roofjobs` in ASCII) that PostgreSQL's enqueue chunks
/// and cancellations take, one at a time, as SQLite's single writer runs them: a cancellation
/// sees every batch that asked for a job, and two batches upserting the same jobs in other
/// orders never deadlock. Claims, completions and failures do not take it.
pub(super) const ENQUEUE_LOCK: i64 = 0x726f_6f66_6a6f_6273;

/// The statements whose SQL differs between the backends.
pub(super) struct Dialect {
    /// Claims up to `$4` jobs (queued, or running with a lease that ended before `$3`) for claim
    /// `$2` until `$1`, answering the claimed rows. SQLite has one writer, so `UPDATE ...
    /// RETURNING` claims atomically; PostgreSQL picks its rows with `FOR UPDATE SKIP LOCKED`,
    /// so two replicas never take the same job and none waits for another's.
    pub claim: &'static str,
    /// A statement run first in each enqueue chunk and cancellation, `$1` bound to
    /// [`ENQUEUE_LOCK`] (SQLite's write transaction already serialises them).
    pub serialise_enqueues: Option<&'static str>,
    /// Predictions of `$1` and `$2`, by `osm_id` in its bytes' order (SQLite's text order;
    /// PostgreSQL's `COLLATE "C"`, whatever the database's locale).
    pub predictions_of: &'static str,
    /// Predictions whose box meets `$1..$4` (west, east, south, north), at most `$5`, in the
    /// same order.
    pub predictions_in: &'static str,
    /// Whether a stored prediction is announced to the replicas (`pg_notify`).
    pub announces_predictions: bool,
}

pub(super) const SQLITE: Dialect = Dialect {
    claim: "UPDATE roof_jobs SET state = 'running', lease_until = $1, claim = $2, \
            attempts = attempts + 1, updated_at = $3 WHERE id IN (SELECT id FROM roof_jobs \
            WHERE state = 'queued' OR (state = 'running' AND lease_until < $3) ORDER BY id \
            LIMIT $4) \
            RETURNING id, osm_id, footprint_hash, imagery_id, model_id, footprint, attempts",
    serialise_enqueues: None,
    predictions_of: concat!(
        prediction_columns!(),
        " WHERE imagery_id = $1 AND model_id = $2 ORDER BY osm_id"
    ),
    predictions_in: concat!(
        prediction_columns!(),
        " WHERE max_lon >= $1 AND min_lon <= $2 AND max_lat >= $3 AND min_lat <= $4 \
         ORDER BY osm_id LIMIT $5"
    ),
    announces_predictions: false,
};

pub(super) const POSTGRES: Dialect = Dialect {
    claim: "WITH picked AS (SELECT id FROM roof_jobs WHERE state = 'queued' \
            OR (state = 'running' AND lease_until < $3) ORDER BY id LIMIT $4 \
            FOR UPDATE SKIP LOCKED) \
            UPDATE roof_jobs j SET state = 'running', lease_until = $1, claim = $2, \
            attempts = j.attempts + 1, updated_at = $3 FROM picked WHERE j.id = picked.id \
            RETURNING j.id, j.osm_id, j.footprint_hash, j.imagery_id, j.model_id, j.footprint, \
            j.attempts",
    serialise_enqueues: Some("SELECT pg_advisory_xact_lock($1)"),
    predictions_of: concat!(
        prediction_columns!(),
        " WHERE imagery_id = $1 AND model_id = $2 ORDER BY osm_id COLLATE \"C\""
    ),
    predictions_in: concat!(
        prediction_columns!(),
        " WHERE max_lon >= $1 AND min_lon <= $2 AND max_lat >= $3 AND min_lat <= $4 \
         ORDER BY osm_id COLLATE \"C\" LIMIT $5"
    ),
    announces_predictions: true,
};

//! [`RoofJobQueue`] on PostgreSQL, shared by every replica: a claim picks its rows with
//! `FOR UPDATE SKIP LOCKED` and takes them in the same statement, so two workers (in one process
//! or in many) never take the same job and none waits for another's. Predictions come in the
//! order of their `osm_id`'s bytes (`COLLATE "C"`), as SQLite orders text, whatever the
//! database's locale.

use super::prediction_note::{PREDICTION_CHANNEL, PredictionNote};
use super::queue::{
    BatchCounts, BatchProgress, ClaimedJob, JobError, MAX_ATTEMPTS, NewJob, RoofJobQueue,
    StoredPrediction, footprint_hash, ring_bounds,
};
use super::rows::{
    ENQUEUE_CHUNK, claimed_of_row, empty_states, lease_end, now_ms, prediction_columns,
    prediction_of_row, random_claim, ring_json,
};
use super::token::random_token;
use crate::roofs::classifier::Prediction;
use citymesh_core::geo::GeoBbox;
use sqlx::{PgPool, Row};
use std::collections::BTreeMap;
use std::time::Duration;

/// The transaction-scoped advisory lock (`roofjobs` in ASCII) that the chunks of enqueued batches
/// and cancellations take, one at a time, as SQLite's single writer would run them: a
/// cancellation sees every batch that asked for a job, and two batches upserting the same jobs in
/// other orders never deadlock. Claims, completions and failures do not take it.
const ENQUEUE_LOCK: i64 = 0x726f_6f66_6a6f_6273;

#[derive(Clone)]
pub struct PgJobQueue {
    pool: PgPool,
}

impl PgJobQueue {
    pub fn new(pool: PgPool) -> Self {
        Self { pool }
    }

    /// The database the queue lives in.
    pub fn pool(&self) -> &PgPool {
        &self.pool
    }
}

/// Takes [`ENQUEUE_LOCK`] until the transaction ends.
async fn lock_enqueue(tx: &mut sqlx::PgConnection) -> Result<(), JobError> {
    sqlx::query("SELECT pg_advisory_xact_lock($1)")
        .bind(ENQUEUE_LOCK)
        .execute(tx)
        .await?;
    Ok(())
}

impl RoofJobQueue for PgJobQueue {
    async fn enqueue(
        &self,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        jobs: &[NewJob],
        skipped: BTreeMap<String, u64>,
    ) -> Result<(String, BatchCounts), JobError> {
        let now = now_ms();
        let token = random_token()?;
        let batch: i64 = sqlx::query(
            "INSERT INTO roof_batches (created_at, bbox, imagery_id, model_id, counts, token) \
             VALUES ($1, $2, $3, $4, '{}', $5) RETURNING id",
        )
        .bind(now)
        .bind(bbox)
        .bind(imagery_id)
        .bind(model_id)
        .bind(&token)
        .fetch_one(&self.pool)
        .await?
        .get(0);
        let mut counts = BatchCounts {
            skipped,
            ..BatchCounts::default()
        };
        // In chunks, each its own short transaction: a district's thousands of upserts never
        // hold the enqueue lock long enough to keep other batches or cancellations waiting.
        for chunk in jobs.chunks(ENQUEUE_CHUNK) {
            let mut tx = self.pool.begin().await?;
            lock_enqueue(&mut tx).await?;
            for job in chunk {
                let hash = footprint_hash(&job.footprint);
                // A job that failed for good or was cancelled is queued again by a new batch.
                let inserted = sqlx::query(
                    "INSERT INTO roof_jobs (batch_id, osm_id, footprint_hash, imagery_id, model_id, \
                     footprint, state, updated_at) VALUES ($1, $2, $3, $4, $5, $6, 'queued', $7) \
                     ON CONFLICT (osm_id, footprint_hash, imagery_id, model_id) DO UPDATE SET \
                     batch_id = EXCLUDED.batch_id, state = 'queued', attempts = 0, error = NULL, \
                     lease_until = NULL, updated_at = EXCLUDED.updated_at \
                     WHERE roof_jobs.state IN ('failed', 'cancelled')",
                )
                .bind(batch)
                .bind(&job.osm_id)
                .bind(&hash)
                .bind(imagery_id)
                .bind(model_id)
                .bind(ring_json(&job.footprint))
                .bind(now)
                .execute(&mut *tx)
                .await?
                .rows_affected();
                if inserted == 1 {
                    counts.queued += 1;
                } else {
                    counts.already += 1;
                }
                // The job is this batch's too, whichever batch queued it: its progress counts it
                // and deleting another batch leaves it queued.
                sqlx::query(
                    "INSERT INTO roof_batch_jobs (batch_id, job_id) SELECT $1, id FROM roof_jobs \
                     WHERE osm_id = $2 AND footprint_hash = $3 AND imagery_id = $4 \
                     AND model_id = $5 ON CONFLICT DO NOTHING",
                )
                .bind(batch)
                .bind(&job.osm_id)
                .bind(&hash)
                .bind(imagery_id)
                .bind(model_id)
                .execute(&mut *tx)
                .await?;
            }
            tx.commit().await?;
        }
        sqlx::query("UPDATE roof_batches SET counts = $1 WHERE id = $2")
            .bind(serde_json::to_string(&counts).unwrap_or_default())
            .bind(batch)
            .execute(&self.pool)
            .await?;
        Ok((token, counts))
    }

    async fn claim(&self, n: u32, lease: Duration) -> Result<Vec<ClaimedJob>, JobError> {
        let now = now_ms();
        let until = lease_end(now, lease);
        let claim = random_claim()?;
        // Rows another claim is taking right now are skipped, not waited for; a row another
        // claim took since this statement began no longer passes the condition when locked.
        let rows = sqlx::query(
            "WITH picked AS (SELECT id FROM roof_jobs WHERE state = 'queued' \
             OR (state = 'running' AND lease_until < $3) ORDER BY id LIMIT $4 \
             FOR UPDATE SKIP LOCKED) \
             UPDATE roof_jobs j SET state = 'running', lease_until = $1, claim = $2, \
             attempts = j.attempts + 1, updated_at = $3 FROM picked WHERE j.id = picked.id \
             RETURNING j.id, j.osm_id, j.footprint_hash, j.imagery_id, j.model_id, j.footprint, \
             j.attempts",
        )
        .bind(until)
        .bind(claim)
        .bind(now)
        .bind(i64::from(n))
        .fetch_all(&self.pool)
        .await?;
        let mut jobs = rows
            .iter()
            .map(|r| claimed_of_row(r, claim))
            .collect::<Result<Vec<_>, JobError>>()?;
        jobs.sort_by_key(|j| j.id);
        Ok(jobs)
    }

    async fn extend(&self, claim: i64, lease: Duration) -> Result<u64, JobError> {
        let now = now_ms();
        Ok(sqlx::query(
            "UPDATE roof_jobs SET lease_until = $1, updated_at = $2 WHERE claim = $3 \
             AND state = 'running'",
        )
        .bind(lease_end(now, lease))
        .bind(now)
        .bind(claim)
        .execute(&self.pool)
        .await?
        .rows_affected())
    }

    async fn complete(
        &self,
        job: &ClaimedJob,
        prediction: Prediction,
        work_ms: f64,
    ) -> Result<bool, JobError> {
        let [west, south, east, north] = ring_bounds(&job.footprint).unwrap_or([0.0; 4]);
        let now = now_ms();
        let p = prediction.probabilities;
        let mut tx = self.pool.begin().await?;
        // Still this claim's job? (A claim whose lease ran out may have been taken over.) The
        // row stays locked until the prediction is stored, so no claim takes it meanwhile.
        let ours = sqlx::query(
            "UPDATE roof_jobs SET state = 'done', lease_until = NULL, error = NULL, \
             updated_at = $1 WHERE id = $2 AND state = 'running' AND claim = $3",
        )
        .bind(now)
        .bind(job.id)
        .bind(job.claim)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        if ours == 0 {
            tx.rollback().await?;
            return Ok(false);
        }
        sqlx::query(
            "INSERT INTO roof_predictions (osm_id, footprint_hash, imagery_id, model_id, p_flat, \
             p_gabled, p_hipped, footprint, min_lon, min_lat, max_lon, max_lat, created_at, \
             work_ms) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14) \
             ON CONFLICT (osm_id, footprint_hash, imagery_id, model_id) DO UPDATE SET \
             p_flat = EXCLUDED.p_flat, p_gabled = EXCLUDED.p_gabled, \
             p_hipped = EXCLUDED.p_hipped, footprint = EXCLUDED.footprint, \
             min_lon = EXCLUDED.min_lon, min_lat = EXCLUDED.min_lat, \
             max_lon = EXCLUDED.max_lon, max_lat = EXCLUDED.max_lat, \
             created_at = EXCLUDED.created_at, work_ms = EXCLUDED.work_ms",
        )
        .bind(&job.osm_id)
        .bind(&job.footprint_hash)
        .bind(&job.imagery_id)
        .bind(&job.model_id)
        .bind(f64::from(p[0]))
        .bind(f64::from(p[1]))
        .bind(f64::from(p[2]))
        .bind(ring_json(&job.footprint))
        .bind(west)
        .bind(south)
        .bind(east)
        .bind(north)
        .bind(now)
        .bind(work_ms)
        .execute(&mut *tx)
        .await?;
        // Every replica hears of it once it is stored (notifications go out at commit).
        let note = PredictionNote {
            osm_id: job.osm_id.clone(),
            footprint_hash: job.footprint_hash.clone(),
            imagery_id: job.imagery_id.clone(),
            model_id: job.model_id.clone(),
            probabilities: p,
            work_ms,
        };
        sqlx::query("SELECT pg_notify($1, $2)")
            .bind(PREDICTION_CHANNEL)
            .bind(serde_json::to_string(&note).unwrap_or_default())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(true)
    }

    async fn states(&self) -> Result<BTreeMap<String, u64>, JobError> {
        let mut states = empty_states();
        for r in sqlx::query("SELECT state, COUNT(*) FROM roof_jobs GROUP BY state")
            .fetch_all(&self.pool)
            .await?
        {
            states.insert(r.get(0), u64::try_from(r.get::<i64, _>(1)).unwrap_or(0));
        }
        Ok(states)
    }

    async fn fail(&self, job: &ClaimedJob, reason: &str, retry: bool) -> Result<bool, JobError> {
        let state = if retry && job.attempts < MAX_ATTEMPTS {
            "queued"
        } else {
            "failed"
        };
        let ours = sqlx::query(
            "UPDATE roof_jobs SET state = $1, lease_until = NULL, error = $2, updated_at = $3 \
             WHERE id = $4 AND state = 'running' AND claim = $5",
        )
        .bind(state)
        .bind(reason)
        .bind(now_ms())
        .bind(job.id)
        .bind(job.claim)
        .execute(&self.pool)
        .await?
        .rows_affected();
        Ok(ours == 1)
    }

    async fn progress(&self, token: &str) -> Result<Option<BatchProgress>, JobError> {
        let Some(row) = sqlx::query(
            "SELECT bbox, imagery_id, model_id, counts, cancelled, id FROM roof_batches \
             WHERE token = $1",
        )
        .bind(token)
        .fetch_optional(&self.pool)
        .await?
        else {
            return Ok(None);
        };
        let counts: BatchCounts =
            serde_json::from_str(&row.get::<String, _>(3)).unwrap_or_default();
        let batch: i64 = row.get(5);
        let mut jobs = empty_states();
        for r in sqlx::query(
            "SELECT j.state, COUNT(*) FROM roof_batch_jobs b JOIN roof_jobs j \
             ON j.id = b.job_id WHERE b.batch_id = $1 GROUP BY j.state",
        )
        .bind(batch)
        .fetch_all(&self.pool)
        .await?
        {
            jobs.insert(r.get(0), u64::try_from(r.get::<i64, _>(1)).unwrap_or(0));
        }
        let finished = jobs["queued"] == 0 && jobs["running"] == 0;
        Ok(Some(BatchProgress {
            id: token.to_owned(),
            bbox: row.get(0),
            imagery_id: row.get(1),
            model_id: row.get(2),
            counts,
            jobs,
            finished,
            cancelled: row.get::<i64, _>(4) != 0,
        }))
    }

    async fn cancel(&self, token: &str) -> Result<Option<u64>, JobError> {
        let mut tx = self.pool.begin().await?;
        // No batch is being queued meanwhile: the links read below are all there are.
        lock_enqueue(&mut tx).await?;
        let Some(batch) =
            sqlx::query("UPDATE roof_batches SET cancelled = 1 WHERE token = $1 RETURNING id")
                .bind(token)
                .fetch_optional(&mut *tx)
                .await?
                .map(|r| r.get::<i64, _>(0))
        else {
            return Ok(None);
        };
        // Only the queued jobs no other live batch asked for: a job two clients want survives
        // the deletion of one's batch. A job a claim is taking now waits for it, then is
        // running and left alone.
        let n = sqlx::query(
            "UPDATE roof_jobs SET state = 'cancelled', updated_at = $1 WHERE state = 'queued' \
             AND id IN (SELECT job_id FROM roof_batch_jobs WHERE batch_id = $2) \
             AND NOT EXISTS (SELECT 1 FROM roof_batch_jobs o JOIN roof_batches b \
             ON b.id = o.batch_id WHERE o.job_id = roof_jobs.id AND o.batch_id <> $2 \
             AND b.cancelled = 0)",
        )
        .bind(now_ms())
        .bind(batch)
        .execute(&mut *tx)
        .await?
        .rows_affected();
        tx.commit().await?;
        Ok(Some(n))
    }

    async fn predictions_of(
        &self,
        imagery_id: &str,
        model_id: &str,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        let rows = sqlx::query(concat!(
            prediction_columns!(),
            " WHERE imagery_id = $1 AND model_id = $2 ORDER BY osm_id COLLATE \"C\""
        ))
        .bind(imagery_id)
        .bind(model_id)
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(prediction_of_row).collect()
    }

    async fn predictions(
        &self,
        bbox: &GeoBbox,
        limit: u32,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        let rows = sqlx::query(concat!(
            prediction_columns!(),
            " WHERE max_lon >= $1 AND min_lon <= $2 AND max_lat >= $3 AND min_lat <= $4 \
             ORDER BY osm_id COLLATE \"C\" LIMIT $5"
        ))
        .bind(bbox.min_lon())
        .bind(bbox.max_lon())
        .bind(bbox.min_lat())
        .bind(bbox.max_lat())
        .bind(i64::from(limit))
        .fetch_all(&self.pool)
        .await?;
        rows.iter().map(prediction_of_row).collect()
    }
}

//! [`RoofJobQueue`] on SQLite: one writer at a time, so `UPDATE ... RETURNING` claims atomically.

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
use sqlx::{Row, SqlitePool};
use std::collections::BTreeMap;
use std::time::Duration;

#[derive(Clone)]
pub struct SqliteJobQueue {
    pool: SqlitePool,
}

impl SqliteJobQueue {
    pub fn new(pool: SqlitePool) -> Self {
        Self { pool }
    }

    /// The cache database the queue lives in.
    pub fn pool(&self) -> &SqlitePool {
        &self.pool
    }
}

impl RoofJobQueue for SqliteJobQueue {
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
             VALUES (?, ?, ?, ?, '{}', ?) RETURNING id",
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
        // hold the database's write lock long enough to starve other writers.
        for chunk in jobs.chunks(ENQUEUE_CHUNK) {
            let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
            for job in chunk {
                let hash = footprint_hash(&job.footprint);
                // A job that failed for good or was cancelled is queued again by a new batch.
                let inserted = sqlx::query(
                    "INSERT INTO roof_jobs (batch_id, osm_id, footprint_hash, imagery_id, model_id, \
                     footprint, state, updated_at) VALUES (?, ?, ?, ?, ?, ?, 'queued', ?) \
                     ON CONFLICT (osm_id, footprint_hash, imagery_id, model_id) DO UPDATE SET \
                     batch_id = excluded.batch_id, state = 'queued', attempts = 0, error = NULL, \
                     lease_until = NULL, updated_at = excluded.updated_at \
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
                    "INSERT OR IGNORE INTO roof_batch_jobs (batch_id, job_id) SELECT ?, id \
                     FROM roof_jobs WHERE osm_id = ? AND footprint_hash = ? AND imagery_id = ? \
                     AND model_id = ?",
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
        sqlx::query("UPDATE roof_batches SET counts = ? WHERE id = ?")
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
        let rows = sqlx::query(
            "UPDATE roof_jobs SET state = 'running', lease_until = ?, claim = ?, \
             attempts = attempts + 1, updated_at = ? WHERE id IN (SELECT id FROM roof_jobs \
             WHERE state = 'queued' OR (state = 'running' AND lease_until < ?) ORDER BY id \
             LIMIT ?) \
             RETURNING id, osm_id, footprint_hash, imagery_id, model_id, footprint, attempts",
        )
        .bind(until)
        .bind(claim)
        .bind(now)
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
            "UPDATE roof_jobs SET lease_until = ?, updated_at = ? WHERE claim = ? \
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
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        // Still this claim's job? (A claim whose lease ran out may have been taken over.)
        let ours = sqlx::query(
            "UPDATE roof_jobs SET state = 'done', lease_until = NULL, error = NULL, updated_at = ? \
             WHERE id = ? AND state = 'running' AND claim = ?",
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
            "INSERT OR REPLACE INTO roof_predictions (osm_id, footprint_hash, imagery_id, model_id, \
             p_flat, p_gabled, p_hipped, footprint, min_lon, min_lat, max_lon, max_lat, created_at, \
             work_ms) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
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
            "UPDATE roof_jobs SET state = ?, lease_until = NULL, error = ?, updated_at = ? \
             WHERE id = ? AND state = 'running' AND claim = ?",
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
             WHERE token = ?",
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
                 ON j.id = b.job_id WHERE b.batch_id = ? GROUP BY j.state",
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
        let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
        let Some(batch) =
            sqlx::query("UPDATE roof_batches SET cancelled = 1 WHERE token = ? RETURNING id")
                .bind(token)
                .fetch_optional(&mut *tx)
                .await?
                .map(|r| r.get::<i64, _>(0))
        else {
            return Ok(None);
        };
        // Only the queued jobs no other live batch asked for: a job two clients want survives
        // the deletion of one's batch.
        let n = sqlx::query(
            "UPDATE roof_jobs SET state = 'cancelled', updated_at = ? WHERE state = 'queued' \
             AND id IN (SELECT job_id FROM roof_batch_jobs WHERE batch_id = ?) \
             AND NOT EXISTS (SELECT 1 FROM roof_batch_jobs o JOIN roof_batches b \
             ON b.id = o.batch_id WHERE o.job_id = roof_jobs.id AND o.batch_id != ? \
             AND b.cancelled = 0)",
        )
        .bind(now_ms())
        .bind(batch)
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
            " WHERE imagery_id = ? AND model_id = ? ORDER BY osm_id"
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
            " WHERE max_lon >= ? AND min_lon <= ? AND max_lat >= ? AND min_lat <= ? \
             ORDER BY osm_id LIMIT ?"
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

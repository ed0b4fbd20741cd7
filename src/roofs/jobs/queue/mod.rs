//! The roof job queue on the opened database: batches of buildings to classify, kept so nothing
//! is lost on a crash, claimed by workers under a lease so a worker that dies leaves its jobs to
//! another, and the predictions they store. One type for both backends: each statement is
//! written once (`statements.rs`), run on either pool by `on_pool!`, with a [`Dialect`] only
//! where the SQL really differs.

mod rows;
mod statements;

use super::job::{
    BatchCounts, BatchProgress, ClaimedJob, JobError, MAX_ATTEMPTS, NewJob, StoredPrediction,
    footprint_hash, ring_bounds,
};
use super::prediction_note::{PREDICTION_CHANNEL, PredictionNote};
use super::token::random_token;
use crate::clock::Clock;
use crate::db::{BeginWrite as _, Database, on_pool};
use crate::roofs::classifier::Prediction;
use citymesh_core::geo::GeoBbox;
use rows::{
    ENQUEUE_CHUNK, claimed_of_row, empty_states, lease_end, prediction_of_row, random_claim,
    ring_json,
};
use sqlx::Row;
use statements::{Dialect, ENQUEUE_LOCK, POSTGRES, SQLITE};
use std::collections::BTreeMap;
use std::time::Duration;

/// The queue on the [`Database`] it was made for.
#[derive(Clone)]
pub struct JobQueue {
    db: Database,
    /// What leases and changes are stamped with (tests move a manual one).
    clock: Clock,
}

impl JobQueue {
    pub fn new(db: &Database) -> Self {
        Self {
            db: db.clone(),
            clock: Clock::system(),
        }
    }

    /// The queue with leases and changes stamped by `clock`.
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// The database the queue lives in (the adaptations live there too).
    pub fn database(&self) -> Database {
        self.db.clone()
    }

    fn dialect(&self) -> &'static Dialect {
        match self.db {
            Database::Sqlite(_) => &SQLITE,
            Database::Postgres(_) => &POSTGRES,
        }
    }

    /// Makes a batch and queues a job per building not yet queued or done for these inputs;
    /// answers the batch's token and counts.
    pub async fn enqueue(
        &self,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        jobs: &[NewJob],
        skipped: BTreeMap<String, u64>,
    ) -> Result<(String, BatchCounts), JobError> {
        let now = self.clock.now_ms();
        let token = random_token()?;
        let serialise = self.dialect().serialise_enqueues;
        let mut counts = BatchCounts {
            skipped,
            ..BatchCounts::default()
        };
        on_pool!(&self.db, pool => {
            let batch: i64 = sqlx::query_scalar(statements::NEW_BATCH)
                .bind(now)
                .bind(bbox)
                .bind(imagery_id)
                .bind(model_id)
                .bind(&token)
                .fetch_one(pool)
                .await?;
            // In chunks, each its own short transaction: a district's thousands of upserts
            // never hold the write lock long enough to starve other writers.
            for chunk in jobs.chunks(ENQUEUE_CHUNK) {
                let mut tx = pool.begin_write().await?;
                if let Some(sql) = serialise {
                    sqlx::query(sql).bind(ENQUEUE_LOCK).execute(&mut *tx).await?;
                }
                for job in chunk {
                    let hash = footprint_hash(&job.footprint);
                    let inserted = sqlx::query(statements::UPSERT_JOB)
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
                    // The job is this batch's too: its progress counts it, and deleting
                    // another batch leaves it queued.
                    sqlx::query(statements::LINK_JOB)
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
            sqlx::query(statements::BATCH_COUNTS)
                .bind(serde_json::to_string(&counts).unwrap_or_default())
                .bind(batch)
                .execute(pool)
                .await?;
        });
        Ok((token, counts))
    }

    /// Claims up to `n` jobs (queued, or running with a lease run out) for `lease`.
    pub async fn claim(&self, n: u32, lease: Duration) -> Result<Vec<ClaimedJob>, JobError> {
        let now = self.clock.now_ms();
        let claim = random_claim()?;
        let sql = self.dialect().claim;
        let mut jobs = on_pool!(&self.db, pool => {
            sqlx::query(sql)
                .bind(lease_end(now, lease))
                .bind(claim)
                .bind(now)
                .bind(i64::from(n))
                .fetch_all(pool)
                .await?
                .iter()
                .map(|r| claimed_of_row(r, claim))
                .collect::<Result<Vec<_>, JobError>>()?
        });
        jobs.sort_by_key(|j| j.id);
        Ok(jobs)
    }

    /// Extends the lease of the claim's jobs still running under it to `lease` from now;
    /// answers how many it holds.
    pub async fn extend(&self, claim: i64, lease: Duration) -> Result<u64, JobError> {
        let now = self.clock.now_ms();
        Ok(on_pool!(&self.db, pool => {
            sqlx::query(statements::EXTEND)
                .bind(lease_end(now, lease))
                .bind(now)
                .bind(claim)
                .execute(pool)
                .await?
                .rows_affected()
        }))
    }

    /// Stores the prediction (which took `work_ms`) and marks the job done, in one
    /// transaction, if the job is still this claim's (running, under the same claim); `false`
    /// when its lease ran out and another claim took it, or it was cancelled: then nothing is
    /// stored, so a job is done exactly once. On PostgreSQL every replica hears of it once it
    /// is stored (notifications go out at commit).
    pub async fn complete(
        &self,
        job: &ClaimedJob,
        prediction: Prediction,
        work_ms: f64,
    ) -> Result<bool, JobError> {
        let [west, south, east, north] = ring_bounds(&job.footprint).unwrap_or([0.0; 4]);
        let now = self.clock.now_ms();
        let p = prediction.probabilities;
        let announce = self
            .dialect()
            .announces_predictions
            .then(|| PredictionNote {
                osm_id: job.osm_id.clone(),
                footprint_hash: job.footprint_hash.clone(),
                imagery_id: job.imagery_id.clone(),
                model_id: job.model_id.clone(),
                probabilities: p,
                work_ms,
            });
        Ok(on_pool!(&self.db, pool => {
            let mut tx = pool.begin_write().await?;
            // The row stays locked until the prediction is stored, so no claim takes it
            // meanwhile.
            let ours = sqlx::query(statements::MARK_DONE)
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
            sqlx::query(statements::UPSERT_PREDICTION)
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
            if let Some(note) = &announce {
                sqlx::query("SELECT pg_notify($1, $2)")
                    .bind(PREDICTION_CHANNEL)
                    .bind(serde_json::to_string(note).unwrap_or_default())
                    .execute(&mut *tx)
                    .await?;
            }
            tx.commit().await?;
            true
        }))
    }

    /// Jobs by state, over every batch.
    pub async fn states(&self) -> Result<BTreeMap<String, u64>, JobError> {
        let rows: Vec<(String, i64)> = on_pool!(&self.db, pool => {
            sqlx::query_as(statements::STATES).fetch_all(pool).await?
        });
        Ok(with_counts(empty_states(), rows))
    }

    /// Gives the job back for another attempt, or fails it for good after [`MAX_ATTEMPTS`] or
    /// when `retry` is false; `false` (and nothing changed) when the job is no longer this
    /// claim's.
    pub async fn fail(
        &self,
        job: &ClaimedJob,
        reason: &str,
        retry: bool,
    ) -> Result<bool, JobError> {
        let state = if retry && job.attempts < MAX_ATTEMPTS {
            "queued"
        } else {
            "failed"
        };
        let now = self.clock.now_ms();
        let ours = on_pool!(&self.db, pool => {
            sqlx::query(statements::FAIL)
                .bind(state)
                .bind(reason)
                .bind(now)
                .bind(job.id)
                .bind(job.claim)
                .execute(pool)
                .await?
                .rows_affected()
        });
        Ok(ours == 1)
    }

    /// The batch's progress, `None` if there is no such batch.
    pub async fn progress(&self, token: &str) -> Result<Option<BatchProgress>, JobError> {
        let found = on_pool!(&self.db, pool => {
            match sqlx::query(statements::BATCH).bind(token).fetch_optional(pool).await? {
                None => None,
                Some(row) => {
                    let batch: i64 = row.get(5);
                    let states: Vec<(String, i64)> = sqlx::query_as(statements::BATCH_STATES)
                        .bind(batch)
                        .fetch_all(pool)
                        .await?;
                    Some((
                        [
                            row.get::<String, _>(0),
                            row.get(1),
                            row.get(2),
                            row.get(3),
                        ],
                        row.get::<i64, _>(4) != 0,
                        states,
                    ))
                }
            }
        });
        let Some(([bbox, imagery_id, model_id, counts], cancelled, states)) = found else {
            return Ok(None);
        };
        let jobs = with_counts(empty_states(), states);
        let finished = jobs["queued"] == 0 && jobs["running"] == 0;
        Ok(Some(BatchProgress {
            id: token.to_owned(),
            bbox,
            imagery_id,
            model_id,
            counts: serde_json::from_str(&counts).unwrap_or_default(),
            jobs,
            finished,
            cancelled,
        }))
    }

    /// Cancels the batch's queued jobs that no other live batch asked for (a job two clients
    /// want survives the deletion of one's batch; a job a claim is taking now is running and
    /// left alone); `None` if there is no such batch.
    pub async fn cancel(&self, token: &str) -> Result<Option<u64>, JobError> {
        let now = self.clock.now_ms();
        let serialise = self.dialect().serialise_enqueues;
        Ok(on_pool!(&self.db, pool => {
            let mut tx = pool.begin_write().await?;
            // No batch is being queued meanwhile: the links read below are all there are.
            if let Some(sql) = serialise {
                sqlx::query(sql).bind(ENQUEUE_LOCK).execute(&mut *tx).await?;
            }
            let batch: Option<i64> = sqlx::query_scalar(statements::CANCEL_BATCH)
                .bind(token)
                .fetch_optional(&mut *tx)
                .await?;
            match batch {
                None => None,
                Some(batch) => {
                    let n = sqlx::query(statements::CANCEL_JOBS)
                        .bind(now)
                        .bind(batch)
                        .execute(&mut *tx)
                        .await?
                        .rows_affected();
                    tx.commit().await?;
                    Some(n)
                }
            }
        }))
    }

    /// Every prediction made from `imagery_id` by `model_id`.
    pub async fn predictions_of(
        &self,
        imagery_id: &str,
        model_id: &str,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        let sql = self.dialect().predictions_of;
        on_pool!(&self.db, pool => {
            sqlx::query(sql)
                .bind(imagery_id)
                .bind(model_id)
                .fetch_all(pool)
                .await?
                .iter()
                .map(prediction_of_row)
                .collect()
        })
    }

    /// Predictions whose footprint's box meets `bbox`, at most `limit`.
    pub async fn predictions(
        &self,
        bbox: &GeoBbox,
        limit: u32,
    ) -> Result<Vec<StoredPrediction>, JobError> {
        let sql = self.dialect().predictions_in;
        on_pool!(&self.db, pool => {
            sqlx::query(sql)
                .bind(bbox.min_lon())
                .bind(bbox.max_lon())
                .bind(bbox.min_lat())
                .bind(bbox.max_lat())
                .bind(i64::from(limit))
                .fetch_all(pool)
                .await?
                .iter()
                .map(prediction_of_row)
                .collect()
        })
    }
}

/// `states` with the counts of `rows` (state, count) filled in.
fn with_counts(
    mut states: BTreeMap<String, u64>,
    rows: Vec<(String, i64)>,
) -> BTreeMap<String, u64> {
    for (state, n) in rows {
        states.insert(state, u64::try_from(n).unwrap_or(0));
    }
    states
}

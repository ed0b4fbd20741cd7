//! What classification batches may keep in the store. A batch is a row plus a link per building
//! it names, and every `POST /classify` makes one, so without a bound any anonymous client could
//! fill the disk by asking for the same box again and again. So:
//!
//! - a batch's bytes are estimated when it is made ([`batch_bytes`]) and counted against
//!   `--classify-store-mb`, and against the asking client's share of it
//!   (`--classify-client-share-percent`); past its share a client gets 429, past the whole budget
//!   everyone gets 503, both with `Retry-After`;
//! - a finished batch (no job queued or running) expires `--classify-batch-ttl-s` after its last
//!   job ended: its links are deleted, and its row too unless a job still names it as the batch
//!   that queued it (then the row stays, without bytes, marked expired). Its predictions stay.
//! - deleting a batch (`DELETE /classify/{id}`) gives its links back at once.
//!
//! The check and the batch's insert are one step in this process (a mutex over both), so
//! concurrent requests cannot all pass the check; replicas sharing PostgreSQL can overshoot the
//! budget by at most one batch each.
//!
//! Statements read the same on both databases (`$n` placeholders).

use super::job::JobError;
use crate::db::{Database, on_pool};
use sqlx::Row;
use std::time::{Duration, Instant};

/// What a batch's row is estimated to take in the store (bbox, ids, counts, token, indexes).
pub const BATCH_ROW_BYTES: u64 = 512;
/// What one building's link to a batch is estimated to take (its row and two index entries, on
/// SQLite's pages): measured as about 108 bytes per link on Kirchfeld's batches.
pub const LINK_BYTES: u64 = 112;
/// Batches expired per statement round.
const EXPIRE_CHUNK: i64 = 256;
/// The longest between two sweeps for expired batches.
const MAX_SWEEP_EVERY: Duration = Duration::from_secs(60);

/// The estimated bytes of a batch naming `links` buildings.
pub fn batch_bytes(links: usize) -> u64 {
    BATCH_ROW_BYTES.saturating_add(LINK_BYTES.saturating_mul(links as u64))
}

/// The bounds on batches.
#[derive(Debug, Clone, Copy)]
pub struct BatchLimits {
    /// Bytes all live batches may take.
    pub max_bytes: u64,
    /// Bytes one client's live batches may take.
    pub client_bytes: u64,
    /// How long a finished batch is kept after its last job ended.
    pub ttl: Duration,
}

impl Default for BatchLimits {
    fn default() -> Self {
        Self {
            max_bytes: 64 << 20,
            client_bytes: 16 << 20,
            ttl: Duration::from_secs(86_400),
        }
    }
}

/// Why a batch was not made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// The client's live batches hold `used` bytes; with this one they would pass its share.
    OverShare { used: u64, share: u64 },
    /// All live batches hold `used` bytes; with this one they would pass the budget.
    OverBudget { used: u64, max: u64 },
}

/// The batches' bytes, and the right to make one.
pub struct BatchBudget {
    db: Database,
    pub limits: BatchLimits,
    /// Held from the check to the batch's insert.
    admitting: tokio::sync::Mutex<()>,
    last_sweep: std::sync::Mutex<Option<Instant>>,
}

/// The right to make one batch, held until it is recorded.
pub struct Admission<'a> {
    _one_at_a_time: tokio::sync::MutexGuard<'a, ()>,
}

impl BatchBudget {
    pub fn new(db: Database, limits: BatchLimits) -> Self {
        Self {
            db,
            limits,
            admitting: tokio::sync::Mutex::new(()),
            last_sweep: std::sync::Mutex::new(None),
        }
    }

    /// Whether a batch of `bytes` from `client` fits; if so, the admission to make it under
    /// (recorded with [`Self::record`]). Expired batches are swept first when a sweep is due or
    /// the batch would not fit.
    pub async fn admit(
        &self,
        client: &str,
        bytes: u64,
    ) -> Result<Result<Admission<'_>, Refusal>, JobError> {
        let guard = self.admitting.lock().await;
        if self.sweep_due() {
            self.sweep().await?;
        }
        let mut refusal = self.check(client, bytes).await?;
        if refusal.is_some() && !self.swept_just_now() {
            self.sweep().await?;
            refusal = self.check(client, bytes).await?;
        }
        Ok(match refusal {
            Some(r) => Err(r),
            None => Ok(Admission {
                _one_at_a_time: guard,
            }),
        })
    }

    async fn check(&self, client: &str, bytes: u64) -> Result<Option<Refusal>, JobError> {
        let (all, mine) = self.usage(client).await?;
        if mine.saturating_add(bytes) > self.limits.client_bytes {
            return Ok(Some(Refusal::OverShare {
                used: mine,
                share: self.limits.client_bytes,
            }));
        }
        if all.saturating_add(bytes) > self.limits.max_bytes {
            return Ok(Some(Refusal::OverBudget {
                used: all,
                max: self.limits.max_bytes,
            }));
        }
        Ok(None)
    }

    /// Records who made the batch `token` and what it takes; ends the admission.
    pub async fn record(
        &self,
        _admission: Admission<'_>,
        token: &str,
        client: &str,
        bytes: u64,
    ) -> Result<(), JobError> {
        let sql = "UPDATE roof_batches SET client = $1, bytes = $2 WHERE token = $3";
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(client)
            .bind(i64::try_from(bytes).unwrap_or(i64::MAX))
            .bind(token)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
    }

    /// Bytes of all live batches and of `client`'s.
    pub async fn usage(&self, client: &str) -> Result<(u64, u64), JobError> {
        // PostgreSQL sums BIGINT as NUMERIC: cast back.
        let sql = "SELECT CAST(COALESCE(SUM(bytes), 0) AS BIGINT), \
                   CAST(COALESCE(SUM(CASE WHEN client = $1 THEN bytes ELSE 0 END), 0) AS BIGINT) \
                   FROM roof_batches WHERE expired = 0";
        let (all, mine): (i64, i64) = on_pool!(&self.db, pool => {
            let row = sqlx::query(sql).bind(client).fetch_one(pool).await?;
            (row.try_get(0)?, row.try_get(1)?)
        });
        Ok((
            u64::try_from(all).unwrap_or(0),
            u64::try_from(mine).unwrap_or(0),
        ))
    }

    /// A deleted batch's links are gone at once (its queued jobs were cancelled): it keeps only
    /// its row's bytes.
    pub async fn release(&self, token: &str) -> Result<(), JobError> {
        let links = "DELETE FROM roof_batch_jobs WHERE batch_id = \
                     (SELECT id FROM roof_batches WHERE token = $1)";
        let row = "UPDATE roof_batches SET bytes = $1 WHERE token = $2";
        on_pool!(&self.db, pool => {
            let mut tx = pool.begin().await?;
            sqlx::query(links).bind(token).execute(&mut *tx).await?;
            sqlx::query(row)
                .bind(BATCH_ROW_BYTES as i64)
                .bind(token)
                .execute(&mut *tx)
                .await?;
            tx.commit().await?;
        });
        Ok(())
    }

    /// Whether the batch `token` expired (and so is gone for clients).
    pub async fn is_expired(&self, token: &str) -> Result<bool, JobError> {
        let sql = "SELECT expired FROM roof_batches WHERE token = $1";
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(token)
            .fetch_optional(pool)
            .await?
            .is_some_and(|r| r.get::<i64, _>(0) != 0)))
    }

    fn sweep_due(&self) -> bool {
        let every = self.limits.ttl.min(MAX_SWEEP_EVERY);
        let last = self.last_sweep.lock().map_or(None, |l| *l);
        last.is_none_or(|t| t.elapsed() >= every)
    }

    fn swept_just_now(&self) -> bool {
        self.last_sweep
            .lock()
            .map_or(None, |l| *l)
            .is_some_and(|t| t.elapsed() < Duration::from_secs(1))
    }

    async fn sweep(&self) -> Result<u64, JobError> {
        let cutoff = crate::clock::Clock::system()
            .now_ms()
            .saturating_sub(i64::try_from(self.limits.ttl.as_millis()).unwrap_or(i64::MAX));
        let n = self.expire(cutoff).await?;
        if let Ok(mut last) = self.last_sweep.lock() {
            *last = Some(Instant::now());
        }
        if n > 0 {
            tracing::debug!(expired = n, "classification batches expired");
        }
        Ok(n)
    }

    /// Expires the finished batches made before `cutoff` (ms) whose jobs all ended before it;
    /// answers how many.
    pub async fn expire(&self, cutoff: i64) -> Result<u64, JobError> {
        let finished = "SELECT id FROM roof_batches b WHERE b.expired = 0 AND b.created_at <= $1 \
             AND NOT EXISTS (SELECT 1 FROM roof_batch_jobs l JOIN roof_jobs j ON j.id = l.job_id \
             WHERE l.batch_id = b.id AND (j.state IN ('queued', 'running') OR j.updated_at > $1)) \
             ORDER BY b.id LIMIT $2";
        let links = "DELETE FROM roof_batch_jobs WHERE batch_id = $1";
        let row = "DELETE FROM roof_batches WHERE id = $1 AND NOT EXISTS \
                   (SELECT 1 FROM roof_jobs WHERE batch_id = $1)";
        let keep = "UPDATE roof_batches SET expired = 1, cancelled = 1, bytes = 0 WHERE id = $1";
        let mut expired = 0u64;
        loop {
            let ids: Vec<i64> = on_pool!(&self.db, pool => sqlx::query(finished)
                .bind(cutoff)
                .bind(EXPIRE_CHUNK)
                .fetch_all(pool)
                .await?
                .iter()
                .map(|r| r.get::<i64, _>(0))
                .collect());
            on_pool!(&self.db, pool => {
                let mut tx = pool.begin().await?;
                for id in &ids {
                    sqlx::query(links).bind(id).execute(&mut *tx).await?;
                    let gone = sqlx::query(row).bind(id).execute(&mut *tx).await?.rows_affected();
                    if gone == 0 {
                        sqlx::query(keep).bind(id).execute(&mut *tx).await?;
                    }
                }
                tx.commit().await?;
            });
            expired += ids.len() as u64;
            if (ids.len() as i64) < EXPIRE_CHUNK {
                return Ok(expired);
            }
        }
    }
}

//! The adaptations kept in the server's database (`roof_adaptations`, SQLite or PostgreSQL):
//! one running per imagery at most, under a lease; progress; outcomes; the head in use.

use super::run::AdaptFailure;
use super::{AdaptationStatus, ClassCounts, Lease};
use crate::db::{Database, on_pool};
use crate::roofs::classifier::head::RoofHead;
use crate::roofs::jobs::JobError;
use sqlx::{ColumnIndex, Decode, Row, Type};

/// The adaptations in the server's database.
#[derive(Clone)]
pub struct AdaptationStore {
    db: Database,
}

impl AdaptationStore {
    pub fn new(db: Database) -> Self {
        Self { db }
    }

    /// Marks adaptations left running by a process that stopped as failed: on SQLite (one
    /// process per database) all of them; on PostgreSQL, shared by replicas, only those whose
    /// lease ran out (a live replica's adaptation goes on).
    pub async fn interrupt_running(&self) -> Result<u64, JobError> {
        let sql = match &self.db {
            Database::Sqlite(_) => {
                "UPDATE roof_adaptations SET state = 'failed', error = 'interrupted by a \
                 restart; ask again', updated_at = $1 WHERE state = 'running'"
            }
            Database::Postgres(_) => {
                "UPDATE roof_adaptations SET state = 'failed', error = 'its server stopped before \
                 it ended (its lease ran out); ask again', updated_at = $1 WHERE state = 'running' \
                 AND (lease_until IS NULL OR lease_until <= $1)"
            }
        };
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(crate::clock::Clock::system().now_ms())
            .execute(pool)
            .await?
            .rows_affected()))
    }

    /// Whether an adaptation is running for this imagery.
    pub async fn running(&self, imagery_id: &str) -> Result<Option<String>, JobError> {
        let sql =
            "SELECT id FROM roof_adaptations WHERE imagery_id = $1 AND state = 'running' LIMIT 1";
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(imagery_id)
            .fetch_optional(pool)
            .await?
            .map(|r| r.get::<String, _>(0))))
    }

    /// Starts an adaptation, unless one is running for this imagery: the check and the insert
    /// are one statement (a unique index over the running ones), so of concurrent requests one
    /// starts. A running one whose lease ran out (its process died) is failed first. Answers the
    /// running adaptation's id when one is.
    pub async fn start(
        &self,
        id: &str,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        examples: [usize; 3],
        lease: &Lease,
    ) -> Result<Option<String>, JobError> {
        let now = crate::clock::Clock::system().now_ms();
        let stale = "UPDATE roof_adaptations SET state = 'failed', error = 'its server stopped \
                     before it ended (its lease ran out); ask again', updated_at = $1 \
                     WHERE imagery_id = $2 AND state = 'running' \
                     AND (lease_until IS NULL OR lease_until <= $1)";
        let insert = "INSERT INTO roof_adaptations (id, created_at, updated_at, bbox, imagery_id, \
                      model_id, state, examples, owner, lease_until) \
                      VALUES ($1, $2, $2, $3, $4, $5, 'running', $6, $7, $8)";
        let examples = serde_json::to_string(&examples).unwrap_or_default();
        let inserted = on_pool!(&self.db, pool => {
            sqlx::query(stale).bind(now).bind(imagery_id).execute(pool).await?;
            sqlx::query(insert)
                .bind(id)
                .bind(now)
                .bind(bbox)
                .bind(imagery_id)
                .bind(model_id)
                .bind(&examples)
                .bind(&lease.owner)
                .bind(lease.end(now))
                .execute(pool)
                .await
                .map(|r| r.rows_affected())
        });
        match inserted {
            Ok(_) => Ok(None),
            Err(sqlx::Error::Database(d)) if d.is_unique_violation() => {
                Ok(Some(self.running(imagery_id).await?.unwrap_or_default()))
            }
            Err(e) => Err(e.into()),
        }
    }

    /// Extends a running adaptation's lease; `false` when it is no longer running under this
    /// owner (cancelled, or failed by another process after its lease ran out).
    pub async fn extend(&self, id: &str, lease: &Lease) -> Result<bool, JobError> {
        let sql = "UPDATE roof_adaptations SET lease_until = $1 WHERE id = $2 AND owner = $3 \
                   AND state = 'running'";
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(lease.end(crate::clock::Clock::system().now_ms()))
            .bind(id)
            .bind(&lease.owner)
            .execute(pool)
            .await?
            .rows_affected())
            == 1)
    }

    /// Records the examples found for a running adaptation.
    pub async fn set_examples(&self, id: &str, examples: [usize; 3]) -> Result<(), JobError> {
        let sql = "UPDATE roof_adaptations SET examples = $1, updated_at = $2 WHERE id = $3";
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(serde_json::to_string(&examples).unwrap_or_default())
            .bind(crate::clock::Clock::system().now_ms())
            .bind(id)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
    }

    /// Ends an adaptation a client no longer wants: a running one is `cancelled` (its work
    /// stops), a done one `withdrawn` (its head is no longer used). Answers the state it had
    /// (`None`: no such adaptation); other states are left as they are.
    pub async fn cancel(&self, id: &str) -> Result<Option<String>, JobError> {
        let Some(before) = self.get(id).await?.map(|a| a.state) else {
            return Ok(None);
        };
        let sql = "UPDATE roof_adaptations SET state = $1, error = $2, updated_at = $3 \
                   WHERE id = $4 AND state = $5";
        let (to, why) = match before.as_str() {
            "running" => ("cancelled", "cancelled by a client"),
            "done" => (
                "withdrawn",
                "withdrawn by a client: its head is no longer in use",
            ),
            _ => return Ok(Some(before)),
        };
        let changed = on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(to)
            .bind(why)
            .bind(crate::clock::Clock::system().now_ms())
            .bind(id)
            .bind(&before)
            .execute(pool)
            .await?
            .rows_affected());
        if changed == 0 {
            // It ended meanwhile: answer what it is now.
            return Ok(self.get(id).await?.map(|a| a.state));
        }
        Ok(Some(before))
    }

    /// Starts an adaptation as [`Self::start`] does, failing when one is running.
    pub async fn create(
        &self,
        id: &str,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        examples: [usize; 3],
        lease: &Lease,
    ) -> Result<(), JobError> {
        match self
            .start(id, bbox, imagery_id, model_id, examples, lease)
            .await?
        {
            None => Ok(()),
            Some(running) => Err(JobError::Corrupt(format!(
                "adaptation {running} is running for this imagery"
            ))),
        }
    }

    pub(super) async fn progress(
        &self,
        id: &str,
        cropped: usize,
        failed: usize,
    ) -> Result<(), JobError> {
        let sql = "UPDATE roof_adaptations SET cropped = $1, crop_failed = $2, updated_at = $3 \
                   WHERE id = $4";
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(cropped as i64)
            .bind(failed as i64)
            .bind(crate::clock::Clock::system().now_ms())
            .bind(id)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
    }

    /// Records an outcome, if the adaptation is still running (not cancelled meanwhile):
    /// `done` with a head put in use, `not_better` with a head that did not beat the shipped
    /// one (kept, not used), `too_few` / `failed` with why. Answers whether it was recorded.
    pub async fn record(
        &self,
        id: &str,
        outcome: &Result<RoofHead, AdaptFailure>,
        in_use: bool,
    ) -> Result<bool, JobError> {
        match outcome {
            Ok(head) if in_use => self.finish(id, "done", Some(head), None).await,
            Ok(head) => {
                let why = format!(
                    "the head's cross-validated accuracy ({:.3}) does not beat the shipped head's \
                     ({:.3}) on the same examples: it is kept but not used (start the server \
                     with --adapt-accept-any to use such heads)",
                    head.report.accuracy, head.report.shipped_accuracy
                );
                self.finish(id, "not_better", Some(head), Some(&why)).await
            }
            Err(e @ AdaptFailure::TooFew(_)) => {
                self.finish(id, "too_few", None, Some(&e.to_string())).await
            }
            Err(e @ AdaptFailure::Failed(_)) => {
                self.finish(id, "failed", None, Some(&e.to_string())).await
            }
        }
    }

    async fn finish(
        &self,
        id: &str,
        state: &str,
        head: Option<&RoofHead>,
        error: Option<&str>,
    ) -> Result<bool, JobError> {
        let sql = "UPDATE roof_adaptations SET state = $1, head = $2, head_id = $3, report = $4, \
                   error = $5, updated_at = $6, lease_until = NULL \
                   WHERE id = $7 AND state = 'running'";
        let head_json = head.and_then(|h| serde_json::to_string(h).ok());
        let head_id = head.map(RoofHead::id);
        let report = head.and_then(|h| serde_json::to_string(&h.report).ok());
        let changed = on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(state)
            .bind(&head_json)
            .bind(&head_id)
            .bind(&report)
            .bind(error)
            .bind(crate::clock::Clock::system().now_ms())
            .bind(id)
            .execute(pool)
            .await?
            .rows_affected());
        Ok(changed == 1)
    }

    pub async fn get(&self, id: &str) -> Result<Option<AdaptationStatus>, JobError> {
        let sql = "SELECT id, state, bbox, imagery_id, model_id, examples, cropped, crop_failed, \
                   head_id, report, error FROM roof_adaptations WHERE id = $1";
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(id)
            .fetch_optional(pool)
            .await?
            .as_ref()
            .map(status_of_row)))
    }

    /// The newest head fitted for this imagery and model.
    pub async fn newest_head(
        &self,
        imagery_id: &str,
        model_id: &str,
    ) -> Result<Option<RoofHead>, JobError> {
        let sql = "SELECT head FROM roof_adaptations WHERE imagery_id = $1 AND model_id = $2 \
                   AND state = 'done' AND head IS NOT NULL ORDER BY updated_at DESC LIMIT 1";
        let head = on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(imagery_id)
            .bind(model_id)
            .fetch_optional(pool)
            .await?
            .map(|r| r.get::<String, _>(0)));
        let Some(head) = head else {
            return Ok(None);
        };
        let head: RoofHead = serde_json::from_str(&head)
            .map_err(|e| JobError::Corrupt(format!("stored head: {e}")))?;
        Ok(Some(head))
    }
}

/// An adaptation from a row of `id, state, bbox, imagery_id, model_id, examples, cropped,
/// crop_failed, head_id, report, error`, on either backend.
fn status_of_row<'r, R: Row>(r: &'r R) -> AdaptationStatus
where
    usize: ColumnIndex<R>,
    i64: Decode<'r, R::Database> + Type<R::Database>,
    String: Decode<'r, R::Database> + Type<R::Database>,
    Option<String>: Decode<'r, R::Database> + Type<R::Database>,
{
    let examples: [usize; 3] = serde_json::from_str(&r.get::<String, _>(5)).unwrap_or_default();
    let examples = ClassCounts::of(examples);
    let cropped = r.get::<i64, _>(6).max(0) as u64;
    let crop_failed = r.get::<i64, _>(7).max(0) as u64;
    let state: String = r.get(1);
    let percent = if state == "done" || examples.total() == 0 {
        100.0
    } else {
        100.0 * (cropped + crop_failed) as f64 / examples.total() as f64
    };
    AdaptationStatus {
        id: r.get(0),
        state,
        bbox: r.get(2),
        imagery_id: r.get(3),
        model_id: r.get(4),
        examples,
        cropped,
        crop_failed,
        percent,
        head_id: r.get(8),
        report: r
            .get::<Option<String>, _>(9)
            .and_then(|t| serde_json::from_str(&t).ok()),
        error: r.get(10),
    }
}

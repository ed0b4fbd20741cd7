//! Adapting the roof classifier to the served imagery from OpenStreetMap's own tags
//! (docs/method.md section 13): the buildings of a box that carry a `roof:shape` of the three
//! classes are cropped from the imagery as any building is, the model embeds them, and a head is
//! fitted, cross-validated and stored in the server's database (`roof_adaptations`, SQLite or
//! PostgreSQL); when fitted, it is put in use for this imagery. Progress is kept in the database
//! as it goes, so a client can follow it and nothing reports "running" after a restart.

use super::queue::{JobError, NewJob};
use super::rows::now_ms;
use super::select::{Selection, select_buildings};
use super::service::RoofJobs;
use crate::classifier::head::{AdaptError, MIN_PER_CLASS, RoofHead, fit_head};
use crate::classifier::onnx::OnnxClassifier;
use crate::db::Database;
use crate::imagery::{Imagery, TileMemo, crop_footprint};
use citymesh_core::building::roof::RoofShape;
use citymesh_core::osm::BuildingRecord;
use citymesh_core::roof_image::{Crop, RoofClass};
use serde::Serialize;
use sqlx::{ColumnIndex, Decode, Row, Type};
use std::sync::Arc;
use utoipa::ToSchema;

/// Most tagged buildings of one class used as examples (the first in the data's order): bounds
/// the imagery fetched and the memory held (a crop is 37 KB).
pub const MAX_EXAMPLES_PER_CLASS: usize = 300;

/// Crops before the progress in the database is updated.
const PROGRESS_EVERY: usize = 16;

/// An adaptation as a client sees it.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct AdaptationStatus {
    pub id: String,
    /// `running`, `done` (a head was fitted and is in use), `too_few` (fewer than 20 examples of
    /// a class could be cropped: the shipped head stays) or `failed`.
    pub state: String,
    pub bbox: String,
    pub imagery_id: String,
    /// The model whose embedding the head reads.
    pub model_id: String,
    /// Tagged buildings used as examples, by class.
    pub examples: ClassCounts,
    /// Examples cropped so far, and those whose imagery failed.
    pub cropped: u64,
    pub crop_failed: u64,
    /// Share of the examples cropped, percent (100 once fitted).
    pub percent: f64,
    /// The fitted head's id (predictions made with it record `MODEL+head-ID`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub head_id: Option<String>,
    /// The cross-validated report on the examples: accuracy, confusion matrix, the shipped
    /// head's accuracy on them and the threshold chosen.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub report: Option<serde_json::Value>,
    /// Why it failed or stopped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Counts by class.
#[derive(Debug, Clone, Copy, Default, Serialize, ToSchema)]
pub struct ClassCounts {
    pub flat: u64,
    pub gabled: u64,
    pub hipped: u64,
}

impl ClassCounts {
    pub fn of(counts: [usize; 3]) -> Self {
        Self {
            flat: counts[0] as u64,
            gabled: counts[1] as u64,
            hipped: counts[2] as u64,
        }
    }

    fn total(&self) -> u64 {
        self.flat + self.gabled + self.hipped
    }
}

/// A tagged building to learn from.
pub struct AdaptExample {
    pub job: NewJob,
    pub class: RoofClass,
}

/// The tagged buildings of `records` whose footprint's centre passes `inside`, with their class,
/// at most [`MAX_EXAMPLES_PER_CLASS`] per class.
pub fn tagged_examples<R: std::borrow::Borrow<BuildingRecord>>(
    records: &[R],
    inside: impl Fn(&[[f64; 2]]) -> bool,
) -> Vec<AdaptExample> {
    let class_of: std::collections::HashMap<String, RoofClass> = records
        .iter()
        .map(R::borrow)
        .filter_map(|r| {
            let shape = RoofShape::from_tag(r.tags.get("roof:shape")?)?;
            Some((r.id.to_string(), RoofClass::of_shape(shape)?))
        })
        .collect();
    let (jobs, _) = select_buildings(records, Selection::All);
    let mut taken = [0usize; 3];
    let mut out = Vec::new();
    for job in jobs {
        let Some(&class) = class_of.get(&job.osm_id) else {
            continue;
        };
        if taken[class.index()] >= MAX_EXAMPLES_PER_CLASS || !inside(&job.footprint) {
            continue;
        }
        taken[class.index()] += 1;
        out.push(AdaptExample { job, class });
    }
    out
}

/// How many examples each class has (flat, gabled, hipped).
pub fn class_counts(examples: &[AdaptExample]) -> [usize; 3] {
    let mut counts = [0usize; 3];
    examples.iter().for_each(|e| counts[e.class.index()] += 1);
    counts
}

/// The adaptations in the server's database.
#[derive(Clone)]
pub struct AdaptationStore {
    db: Database,
}

/// Runs `$body` with `$pool` bound to the pool of whichever backend `$db` is: the statements here
/// read the same on both (`$n` placeholders, which SQLite takes too).
macro_rules! on_pool {
    ($db:expr, $pool:ident => $body:expr) => {
        match $db {
            Database::Sqlite($pool) => $body,
            Database::Postgres($pool) => $body,
        }
    };
}

impl AdaptationStore {
    pub fn new(db: Database) -> Self {
        Self { db }
    }

    /// Marks adaptations left running by a process that stopped as failed.
    pub async fn interrupt_running(&self) -> Result<u64, JobError> {
        let sql = "UPDATE roof_adaptations SET state = 'failed', error = 'interrupted by a \
                   restart; ask again', updated_at = $1 WHERE state = 'running'";
        Ok(on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(now_ms())
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

    pub async fn create(
        &self,
        id: &str,
        bbox: &str,
        imagery_id: &str,
        model_id: &str,
        examples: [usize; 3],
    ) -> Result<(), JobError> {
        let now = now_ms();
        let sql = "INSERT INTO roof_adaptations (id, created_at, updated_at, bbox, imagery_id, \
                   model_id, state, examples) VALUES ($1, $2, $3, $4, $5, $6, 'running', $7)";
        let examples = serde_json::to_string(&examples).unwrap_or_default();
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(id)
            .bind(now)
            .bind(now)
            .bind(bbox)
            .bind(imagery_id)
            .bind(model_id)
            .bind(&examples)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
    }

    async fn progress(&self, id: &str, cropped: usize, failed: usize) -> Result<(), JobError> {
        let sql = "UPDATE roof_adaptations SET cropped = $1, crop_failed = $2, updated_at = $3 \
                   WHERE id = $4";
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(cropped as i64)
            .bind(failed as i64)
            .bind(now_ms())
            .bind(id)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
    }

    /// Records an outcome: `done` with the head, or `too_few` / `failed` with why.
    pub async fn record(
        &self,
        id: &str,
        outcome: &Result<RoofHead, AdaptFailure>,
    ) -> Result<(), JobError> {
        match outcome {
            Ok(head) => self.finish(id, "done", Some(head), None).await,
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
    ) -> Result<(), JobError> {
        let sql = "UPDATE roof_adaptations SET state = $1, head = $2, head_id = $3, report = $4, \
                   error = $5, updated_at = $6 WHERE id = $7";
        let head_json = head.and_then(|h| serde_json::to_string(h).ok());
        let head_id = head.map(RoofHead::id);
        let report = head.and_then(|h| serde_json::to_string(&h.report).ok());
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(state)
            .bind(&head_json)
            .bind(&head_id)
            .bind(&report)
            .bind(error)
            .bind(now_ms())
            .bind(id)
            .execute(pool)
            .await
            .map(drop))?;
        Ok(())
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

/// Crops the examples, fits the head and, when fitted, puts it in use. Records progress and the
/// outcome in `store`; never fails the caller (the outcome is in the store).
pub async fn run_adaptation(
    jobs: Arc<RoofJobs>,
    store: AdaptationStore,
    id: String,
    examples: Vec<AdaptExample>,
) {
    let outcome = adapt(&jobs, &store, &id, examples).await;
    if let Err(e) = store.record(&id, &outcome).await {
        tracing::warn!(adaptation = %id, error = %e, "cannot store the adaptation's outcome");
        return;
    }
    if let Ok(head) = &outcome {
        match jobs.use_head(head.clone()).await {
            Ok(()) => tracing::info!(adaptation = %id, head = %head.id(),
                accuracy = head.report.accuracy, "adapted roof head in use"),
            Err(e) => tracing::warn!(adaptation = %id, error = %e, "cannot use the adapted head"),
        }
    }
}

/// Why no head was fitted.
#[derive(Debug)]
pub enum AdaptFailure {
    /// Fewer than 20 examples of a class could be cropped.
    TooFew(String),
    Failed(String),
}

impl std::fmt::Display for AdaptFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFew(m) | Self::Failed(m) => f.write_str(m),
        }
    }
}

async fn adapt(
    jobs: &RoofJobs,
    store: &AdaptationStore,
    id: &str,
    examples: Vec<AdaptExample>,
) -> Result<RoofHead, AdaptFailure> {
    let (Some(imagery), Some(base)) = (jobs.imagery.clone(), jobs.base.clone()) else {
        return Err(AdaptFailure::Failed(
            "no classifier or no imagery is configured".into(),
        ));
    };
    let progress = Progress::Store(store, id);
    fit_on_imagery(&base, &imagery, &examples, &progress).await
}

/// Where cropping progress goes.
pub enum Progress<'a> {
    /// An adaptation's row in the database.
    Store(&'a AdaptationStore, &'a str),
    /// A progress bar on the console.
    Bar(&'a indicatif::ProgressBar),
}

impl Progress<'_> {
    async fn report(&self, cropped: usize, failed: usize) -> Result<(), JobError> {
        match self {
            Self::Store(store, id) => store.progress(id, cropped, failed).await,
            Self::Bar(bar) => {
                bar.set_position((cropped + failed) as u64);
                Ok(())
            }
        }
    }
}

/// Crops the examples from `imagery` as any building is cropped and fits a head on them.
pub async fn fit_on_imagery(
    base: &Arc<OnnxClassifier>,
    imagery: &Imagery,
    examples: &[AdaptExample],
    progress: &Progress<'_>,
) -> Result<RoofHead, AdaptFailure> {
    let failed = |e: &dyn std::fmt::Display| AdaptFailure::Failed(e.to_string());
    let mut tiles = TileMemo::new();
    let mut crops: Vec<Crop> = Vec::with_capacity(examples.len());
    let mut classes: Vec<RoofClass> = Vec::with_capacity(examples.len());
    let mut crop_failed = 0usize;
    for (i, example) in examples.iter().enumerate() {
        match crop_footprint(&example.job.footprint, imagery, &mut tiles).await {
            Ok(crop) => {
                crops.push(crop);
                classes.push(example.class);
            }
            Err(_) => crop_failed += 1,
        }
        if (i + 1) % PROGRESS_EVERY == 0 {
            progress
                .report(crops.len(), crop_failed)
                .await
                .map_err(|e| failed(&e))?;
            // Neighbours share tiles, but each holds 768 KB: keep at most 64 (48 MB).
            if tiles.len() > 64 {
                tiles.clear();
            }
        }
    }
    progress
        .report(crops.len(), crop_failed)
        .await
        .map_err(|e| failed(&e))?;
    let base = base.clone();
    let fitted = tokio::task::spawn_blocking(move || fit_head(&base, &crops, &classes))
        .await
        .map_err(|e| failed(&e))?;
    match fitted {
        Ok(head) => Ok(head),
        Err(e @ AdaptError::TooFew { .. }) => Err(AdaptFailure::TooFew(format!(
            "{e} (at least {MIN_PER_CLASS} per class must be cropped from the imagery)"
        ))),
        Err(e) => Err(failed(&e)),
    }
}

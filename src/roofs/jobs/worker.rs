//! Running roof jobs: claim a few under a lease, fetch their imagery (all tiles of the round at
//! once), crop by the crop rule, classify the crops in one batch, store each prediction. The
//! lease is extended while the round works, so slow imagery never hands running jobs to another
//! worker. Failures of one building fail that job (with a reason; retried when the cause may
//! pass), never the others.

use super::job::{ClaimedJob, JobError};
use super::queue::JobQueue;
use crate::roofs::classifier::{Prediction, RoofClassifier, classify_blocking};
use crate::roofs::imagery::{Imagery, TileMemo, crop_footprint, prefetch_tiles};
use citymesh_core::roof_image::Crop;
use std::sync::Arc;
use std::time::Duration;

/// How workers behave.
#[derive(Debug, Clone, Copy)]
pub struct WorkerConfig {
    /// Jobs claimed at once (and classified in one batch).
    pub claim: u32,
    /// How long a claim holds before another worker may take the job.
    pub lease: Duration,
    /// Pause when the queue is empty.
    pub idle: Duration,
}

impl Default for WorkerConfig {
    fn default() -> Self {
        Self {
            claim: 16,
            lease: Duration::from_secs(120),
            idle: Duration::from_millis(500),
        }
    }
}

/// What one round did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RoundReport {
    /// Jobs the round claimed.
    pub claimed: usize,
    pub done: usize,
    pub failed: usize,
    /// Jobs whose lease ran out before they were stored (another worker has them now).
    pub lost: usize,
    /// Time spent classifying the round's crops.
    pub inference: Duration,
}

/// Called with each job done and its prediction (once stored).
pub type OnDone<'a> = &'a (dyn Fn(&ClaimedJob, &Prediction, f64) + Send + Sync);

/// [`OnDone`], shared by a long-running worker.
pub type SharedOnDone = Arc<dyn Fn(&ClaimedJob, &Prediction, f64) + Send + Sync>;

/// The classifier a long-running worker uses for its next round, and what to do with each job
/// done; `None` when none is loaded.
pub type CurrentModel = dyn Fn() -> Option<(Arc<dyn RoofClassifier>, SharedOnDone)> + Send + Sync;

/// Claims and runs one round of jobs; `Ok(None)` when nothing was queued.
pub async fn run_round(
    queue: &JobQueue,
    imagery: &Imagery,
    classifier: &Arc<dyn RoofClassifier>,
    config: WorkerConfig,
    on_done: OnDone<'_>,
) -> Result<Option<RoundReport>, JobError> {
    let jobs = queue.claim(config.claim, config.lease).await?;
    let Some(claim) = jobs.first().map(|j| j.claim) else {
        return Ok(None);
    };
    let work = work_round(queue, imagery, classifier, jobs, on_done);
    tokio::pin!(work);
    // Extend the lease a third of the way into it, again and again, until the round ends.
    let every = (config.lease / 3).max(Duration::from_millis(10));
    let mut ticks = tokio::time::interval_at(tokio::time::Instant::now() + every, every);
    loop {
        tokio::select! {
            report = &mut work => return report.map(Some),
            _ = ticks.tick() => {
                if let Err(e) = queue.extend(claim, config.lease).await {
                    tracing::warn!(error = %e, "cannot extend a roof job lease");
                }
            }
        }
    }
}

/// Runs claimed jobs to their end.
async fn work_round(
    queue: &JobQueue,
    imagery: &Imagery,
    classifier: &Arc<dyn RoofClassifier>,
    jobs: Vec<ClaimedJob>,
    on_done: OnDone<'_>,
) -> Result<RoundReport, JobError> {
    let round_started = std::time::Instant::now();
    let mut report = RoundReport {
        claimed: jobs.len(),
        ..RoundReport::default()
    };
    let mut tiles = TileMemo::new();
    let footprints: Vec<&[[f64; 2]]> = jobs.iter().map(|j| j.footprint.as_slice()).collect();
    prefetch_tiles(&footprints, imagery, &mut tiles).await;
    let mut ready: Vec<(ClaimedJob, Crop)> = Vec::new();
    for job in jobs {
        match crop_for(&job, imagery, classifier.model_id(), &mut tiles).await {
            Ok(crop) => ready.push((job, crop)),
            Err((reason, retry)) => {
                if queue.fail(&job, &reason, retry).await? {
                    report.failed += 1;
                } else {
                    report.lost += 1;
                }
            }
        }
    }
    if ready.is_empty() {
        return Ok(report);
    }
    let (jobs, crops): (Vec<ClaimedJob>, Vec<Crop>) = ready.into_iter().unzip();
    let started = std::time::Instant::now();
    let classified = classify_blocking(classifier.clone(), crops).await;
    report.inference = started.elapsed();
    match classified {
        Ok(predictions) => {
            let work_ms = round_started.elapsed().as_secs_f64() * 1e3 / jobs.len() as f64;
            for (job, p) in jobs.iter().zip(predictions) {
                if queue.complete(job, p, work_ms).await? {
                    on_done(job, &p, work_ms);
                    report.done += 1;
                } else {
                    report.lost += 1;
                }
            }
        }
        Err(e) => {
            for job in &jobs {
                if queue.fail(job, &format!("classifier: {e}"), true).await? {
                    report.failed += 1;
                } else {
                    report.lost += 1;
                }
            }
        }
    }
    Ok(report)
}

/// The crop of one job, or why not and whether trying again may help.
async fn crop_for(
    job: &ClaimedJob,
    imagery: &Imagery,
    model_id: &str,
    tiles: &mut TileMemo,
) -> Result<Crop, (String, bool)> {
    if job.imagery_id != imagery.spec().id {
        return Err((
            format!("imagery {} is not configured", job.imagery_id),
            false,
        ));
    }
    if job.model_id != model_id {
        return Err((format!("model {} is not loaded", job.model_id), false));
    }
    crop_footprint(&job.footprint, imagery, tiles)
        .await
        .map_err(|f| (f.reason, f.retry))
}

/// Runs rounds for ever (the server aborts it at shutdown; a job it held is taken again when its
/// lease runs out); pauses `idle` when the queue is empty, no classifier is loaded or the store
/// fails. Each round takes the classifier `current` gives then; `after_round` is told what each
/// round did.
pub async fn run_worker(
    queue: JobQueue,
    imagery: Arc<Imagery>,
    current: Arc<CurrentModel>,
    config: WorkerConfig,
    after_round: Arc<dyn Fn(&RoundReport) + Send + Sync>,
) {
    loop {
        let Some((classifier, on_done)) = current() else {
            tokio::time::sleep(config.idle).await;
            continue;
        };
        match run_round(&queue, &imagery, &classifier, config, on_done.as_ref()).await {
            Ok(Some(report)) => after_round(&report),
            Ok(None) => tokio::time::sleep(config.idle).await,
            Err(e) => {
                tracing::warn!(error = %e, "roof job round failed");
                tokio::time::sleep(config.idle).await;
            }
        }
    }
}

//! The server's roof jobs: the queue on the cache database, the predictions tiles use, and the
//! workers that run jobs when a classifier and an imagery service are configured.

use super::index::PredictionIndex;
use super::queue::{JobError, RoofJobQueue};
use super::sqlite::SqliteJobQueue;
use super::worker::{RoundReport, WorkerConfig, run_worker};
use crate::classifier::RoofClassifier;
use crate::imagery::Imagery;
use crate::metrics::{Metrics, StateLabels};
use std::sync::Arc;

pub struct RoofJobs {
    pub queue: SqliteJobQueue,
    /// Predictions of the served imagery and model, by building.
    pub index: Arc<PredictionIndex>,
    /// The imagery predictions are made from (and looked up by).
    pub imagery_id: String,
    pub imagery_attribution: String,
    /// The model predictions are made by: the loaded classifier's, else the built-in model's
    /// (stored predictions serve tiles even where ONNX Runtime is not installed).
    pub model_id: String,
    /// The imagery service, when configured.
    pub imagery: Option<Arc<Imagery>>,
    /// The classifier, when loaded.
    pub classifier: Option<Arc<dyn RoofClassifier>>,
    /// Least top probability that gives a roof its shape.
    pub threshold: f32,
    metrics: Arc<Metrics>,
}

impl RoofJobs {
    /// Loads the stored predictions of `imagery_id` and `model_id`.
    #[allow(clippy::too_many_arguments)]
    pub async fn new(
        queue: SqliteJobQueue,
        imagery_id: String,
        imagery_attribution: String,
        model_id: String,
        imagery: Option<Arc<Imagery>>,
        classifier: Option<Arc<dyn RoofClassifier>>,
        threshold: f32,
        metrics: Arc<Metrics>,
    ) -> Result<Self, JobError> {
        let index = Arc::new(PredictionIndex::load(&queue, &imagery_id, &model_id).await?);
        let jobs = Self {
            queue,
            index,
            imagery_id,
            imagery_attribution,
            model_id,
            imagery,
            classifier,
            threshold,
            metrics,
        };
        jobs.refresh_state_metrics().await;
        Ok(jobs)
    }

    /// The model id as a number for cache keys (its first 16 hex digits).
    pub fn model_key(&self) -> u64 {
        u64::from_str_radix(self.model_id.get(..16).unwrap_or("0"), 16).unwrap_or(0)
    }

    /// Why jobs cannot run here, if they cannot.
    pub fn why_not_running(&self) -> Option<&'static str> {
        if self.classifier.is_none() {
            Some("the roof classifier is not loaded: start the server with --roof-classifier")
        } else if self.imagery.is_none() {
            Some("no imagery service is configured: start the server with --imagery-url")
        } else {
            None
        }
    }

    /// Sets the jobs-by-state gauges from the store.
    pub async fn refresh_state_metrics(&self) {
        match self.queue.states().await {
            Ok(states) => {
                for (state, n) in states {
                    self.metrics
                        .roof_jobs
                        .get_or_create(&StateLabels { state })
                        .set(i64::try_from(n).unwrap_or(i64::MAX));
                }
            }
            Err(e) => tracing::warn!(error = %e, "cannot count roof jobs"),
        }
    }

    /// Starts `n` workers (none without a classifier and imagery); they run until aborted.
    pub fn spawn_workers(
        self: &Arc<Self>,
        n: usize,
        config: WorkerConfig,
    ) -> Vec<tokio::task::JoinHandle<()>> {
        let (Some(imagery), Some(classifier)) = (self.imagery.clone(), self.classifier.clone())
        else {
            return Vec::new();
        };
        (0..n)
            .map(|_| {
                let index = self.index.clone();
                let on_done = Arc::new(
                    move |job: &super::ClaimedJob, p: &crate::classifier::Prediction, ms: f64| {
                        index.insert(job.osm_id.clone(), job.footprint_hash.clone(), *p, ms);
                    },
                );
                let jobs = self.clone();
                let after_round = Arc::new(move |report: &RoundReport| {
                    jobs.metrics
                        .inference_seconds
                        .observe(report.inference.as_secs_f64());
                    let jobs = jobs.clone();
                    tokio::spawn(async move { jobs.refresh_state_metrics().await });
                });
                tokio::spawn(run_worker(
                    self.queue.clone(),
                    imagery.clone(),
                    classifier.clone(),
                    config,
                    on_done,
                    after_round,
                ))
            })
            .collect()
    }
}

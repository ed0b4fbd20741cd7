//! The server's roof jobs: the queue on the server's database, the predictions tiles use, and the
//! workers that run jobs when a classifier and an imagery service are configured.

use super::adapt::{AdaptExample, AdaptPolicy, AdaptationRun, AdaptationStore, run_adaptation};
use super::batch_budget::{BatchBudget, BatchLimits};
use super::index::PredictionIndex;
use super::job::JobError;
use super::queue::JobQueue;
use super::worker::{CurrentModel, RoundReport, SharedOnDone, WorkerConfig, run_worker};
use crate::metrics::{Metrics, StateLabels};
use crate::roofs::classifier::RoofClassifier;
use crate::roofs::classifier::head::{HeadedClassifier, RoofHead};
use crate::roofs::classifier::onnx::OnnxClassifier;
use crate::roofs::imagery::Imagery;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, RwLock};
use tokio_util::sync::CancellationToken;
use tokio_util::task::TaskTracker;

pub struct RoofJobs {
    pub queue: JobQueue,
    /// The imagery predictions are made from (and looked up by).
    pub imagery_id: String,
    pub imagery_attribution: String,
    /// The imagery service, when configured.
    pub imagery: Option<Arc<Imagery>>,
    /// The shipped model loaded with ONNX Runtime, when loaded: heads are fitted on its
    /// embedding.
    pub base: Option<Arc<OnnxClassifier>>,
    /// The model now in use, with its predictions; replaced when a head is adapted.
    active: RwLock<Arc<ActiveModel>>,
    /// Adaptations of the classifier to this imagery.
    pub adaptations: AdaptationStore,
    /// How adaptations run here.
    pub adapt_policy: AdaptPolicy,
    /// The stops of the adaptations running in this process, by id.
    adapting: Mutex<HashMap<String, CancellationToken>>,
    /// Cancelled when the server shuts down: running adaptations stop.
    stopping: CancellationToken,
    /// The adaptations running in this process, waited for on shutdown.
    tasks: TaskTracker,
    /// What classification batches may keep in the store.
    pub batches: BatchBudget,
    metrics: Arc<Metrics>,
}

/// How the server's roof jobs are bounded and run, besides the queue.
#[derive(Debug, Clone)]
pub struct RoofJobsConfig {
    pub batch_limits: BatchLimits,
    pub adapt: AdaptPolicy,
    /// Cancelled when the server shuts down.
    pub stopping: CancellationToken,
}

/// The model predictions are made by now, and the predictions it made.
pub struct ActiveModel {
    /// The loaded classifier's id (`MODEL+head-HEAD` with an adapted head), else the built-in
    /// model's (stored predictions serve tiles even where ONNX Runtime is not installed).
    pub model_id: String,
    /// The classifier, when loaded.
    pub classifier: Option<Arc<dyn RoofClassifier>>,
    /// Predictions of the served imagery and this model, by building.
    pub index: Arc<PredictionIndex>,
    /// Least top probability that gives a roof its shape.
    pub threshold: f32,
}

impl ActiveModel {
    /// The model id as a number for cache keys (xxh3 of the whole id, so a head changes it).
    pub fn model_key(&self) -> u64 {
        xxhash_rust::xxh3::xxh3_64(self.model_id.as_bytes())
    }
}

impl RoofJobs {
    /// Loads the stored predictions of `imagery_id` and `model_id`.
    #[allow(clippy::too_many_arguments)]
    pub async fn new(
        queue: JobQueue,
        imagery_id: String,
        imagery_attribution: String,
        model_id: String,
        imagery: Option<Arc<Imagery>>,
        base: Option<Arc<OnnxClassifier>>,
        threshold: f32,
        metrics: Arc<Metrics>,
        config: RoofJobsConfig,
    ) -> Result<Self, JobError> {
        let index = Arc::new(PredictionIndex::load(&queue, &imagery_id, &model_id).await?);
        let classifier = base.clone().map(|b| b as Arc<dyn RoofClassifier>);
        let adaptations = AdaptationStore::new(queue.database());
        let interrupted = adaptations.interrupt_running().await?;
        if interrupted > 0 {
            tracing::warn!(interrupted, "roof adaptations interrupted by a restart");
        }
        let base_model_id = model_id.clone();
        let jobs = Self {
            batches: BatchBudget::new(queue.database(), config.batch_limits),
            adaptations,
            adapt_policy: config.adapt,
            adapting: Mutex::new(HashMap::new()),
            stopping: config.stopping,
            tasks: TaskTracker::new(),
            queue,
            imagery_id,
            imagery_attribution,
            imagery,
            base,
            active: RwLock::new(Arc::new(ActiveModel {
                model_id,
                classifier,
                index,
                threshold,
            })),
            metrics,
        };
        // The newest head adapted to this imagery for this model is in use, as before a restart.
        if jobs.base.is_some()
            && let Some(head) = jobs
                .adaptations
                .newest_head(&jobs.imagery_id, &base_model_id)
                .await?
        {
            jobs.use_head(head).await?;
        }
        jobs.refresh_state_metrics().await;
        Ok(jobs)
    }

    /// The model in use now.
    pub fn active(&self) -> Arc<ActiveModel> {
        self.active
            .read()
            .map_or_else(|poisoned| poisoned.into_inner().clone(), |a| a.clone())
    }

    /// Puts `head` (fitted for the loaded model) in use for this imagery: new predictions are made
    /// with it and recorded under its id, and tiles with `roofs=classified` use them; the
    /// predictions it made before (after a restart) are loaded.
    pub async fn use_head(&self, head: RoofHead) -> Result<(), JobError> {
        let Some(base) = self.base.clone() else {
            return Err(JobError::Corrupt("no classifier is loaded".into()));
        };
        let threshold = head
            .report
            .threshold
            .probability
            .max(self.active().threshold);
        let headed = HeadedClassifier::new(base, head)
            .map_err(|e| JobError::Corrupt(format!("head: {e}")))?;
        let model_id = headed.model_id().to_owned();
        let index =
            Arc::new(PredictionIndex::load(&self.queue, &self.imagery_id, &model_id).await?);
        let next = Arc::new(ActiveModel {
            model_id,
            classifier: Some(Arc::new(headed)),
            index,
            threshold,
        });
        match self.active.write() {
            Ok(mut a) => *a = next,
            Err(poisoned) => *poisoned.into_inner() = next,
        }
        Ok(())
    }

    /// Puts the newest head adapted to this imagery (and not withdrawn) in use, or the shipped
    /// model when there is none.
    pub async fn use_newest_or_shipped(&self) -> Result<(), JobError> {
        let Some(base) = self.base.clone() else {
            return Ok(());
        };
        let base_id = base.model_id().to_owned();
        if let Some(head) = self
            .adaptations
            .newest_head(&self.imagery_id, &base_id)
            .await?
        {
            return self.use_head(head).await;
        }
        let index = Arc::new(PredictionIndex::load(&self.queue, &self.imagery_id, &base_id).await?);
        let threshold = self.active().threshold;
        let next = Arc::new(ActiveModel {
            model_id: base_id,
            classifier: Some(base as Arc<dyn RoofClassifier>),
            index,
            threshold,
        });
        match self.active.write() {
            Ok(mut a) => *a = next,
            Err(poisoned) => *poisoned.into_inner() = next,
        }
        Ok(())
    }

    /// Runs adaptation `id` in the background on `examples` (its row is started).
    pub fn spawn_adaptation(self: &Arc<Self>, id: String, examples: Vec<AdaptExample>) {
        let stop = self.stopping.child_token();
        if let Ok(mut running) = self.adapting.lock() {
            running.insert(id.clone(), stop.clone());
        }
        let run = AdaptationRun {
            store: self.adaptations.clone(),
            policy: self.adapt_policy.clone(),
            imagery: self.imagery.clone(),
            base: self.base.clone(),
            server_stopping: self.stopping.clone(),
        };
        let jobs = self.clone();
        self.tasks.spawn(async move {
            if let Some(head) = run_adaptation(run, id.clone(), examples, stop).await {
                match jobs.use_head(head.clone()).await {
                    Ok(()) => tracing::info!(adaptation = %id, head = %head.id(),
                        accuracy = head.report.accuracy, "adapted roof head in use"),
                    Err(e) => {
                        tracing::warn!(adaptation = %id, error = %e, "cannot use the adapted head");
                    }
                }
            }
            if let Ok(mut running) = jobs.adapting.lock() {
                running.remove(&id);
            }
        });
    }

    /// Stops adaptation `id` if it runs in this process (other processes stop theirs when
    /// their lease is not extended).
    pub fn stop_adaptation(&self, id: &str) {
        if let Ok(running) = self.adapting.lock()
            && let Some(stop) = running.get(id)
        {
            stop.cancel();
        }
    }

    /// Whether the server is shutting down.
    pub fn is_stopping(&self) -> bool {
        self.stopping.is_cancelled()
    }

    /// Waits (at most `grace`) for the adaptations running here to record their outcome, once
    /// the server's stop (`RoofJobsConfig::stopping`) was cancelled.
    pub async fn shut_down(&self, grace: std::time::Duration) {
        self.stopping.cancel();
        self.tasks.close();
        if tokio::time::timeout(grace, self.tasks.wait())
            .await
            .is_err()
        {
            tracing::warn!("adaptations still stopping after {} s", grace.as_secs_f64());
        }
    }

    /// Loads the active model's predictions again (another replica may have stored some this
    /// one did not hear of).
    pub async fn reload_predictions(&self) -> Result<(), JobError> {
        let active = self.active();
        let index =
            Arc::new(PredictionIndex::load(&self.queue, &self.imagery_id, &active.model_id).await?);
        let next = Arc::new(ActiveModel {
            model_id: active.model_id.clone(),
            classifier: active.classifier.clone(),
            index,
            threshold: active.threshold,
        });
        match self.active.write() {
            // Unless a head was put in use meanwhile (it loaded its own predictions).
            Ok(mut a) if a.model_id == next.model_id => *a = next,
            Ok(_) => {}
            Err(poisoned) => *poisoned.into_inner() = next,
        }
        Ok(())
    }

    /// Why jobs cannot run here, if they cannot.
    pub fn why_not_running(&self) -> Option<&'static str> {
        if self.active().classifier.is_none() {
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

    /// Starts `n` workers (none without a classifier and imagery); they run until aborted. Each
    /// round uses the model in use when it starts.
    pub fn spawn_workers(
        self: &Arc<Self>,
        n: usize,
        config: WorkerConfig,
    ) -> Vec<tokio::task::JoinHandle<()>> {
        let (Some(imagery), Some(_)) = (self.imagery.clone(), self.active().classifier.clone())
        else {
            return Vec::new();
        };
        (0..n)
            .map(|_| {
                let jobs = self.clone();
                let current: Arc<CurrentModel> = Arc::new(move || {
                    let active = jobs.active();
                    let classifier = active.classifier.clone()?;
                    let on_done: SharedOnDone = Arc::new(
                        move |job: &super::ClaimedJob,
                              p: &crate::roofs::classifier::Prediction,
                              ms: f64| {
                            if job.model_id == active.model_id {
                                active.index.insert(
                                    job.osm_id.clone(),
                                    job.footprint_hash.clone(),
                                    *p,
                                    ms,
                                );
                            }
                        },
                    );
                    Some((classifier, on_done))
                });
                let jobs = self.clone();
                let after_round = Arc::new(move |report: &RoundReport| {
                    jobs.metrics
                        .inference_seconds
                        .observe(report.inference.as_secs_f64());
                    let replicas = &jobs.metrics.replicas;
                    replicas.roof_jobs_claimed.inc_by(report.claimed as u64);
                    replicas.roof_jobs_lease_lost.inc_by(report.lost as u64);
                    let jobs = jobs.clone();
                    tokio::spawn(async move { jobs.refresh_state_metrics().await });
                });
                tokio::spawn(run_worker(
                    self.queue.clone(),
                    imagery.clone(),
                    current,
                    config,
                    after_round,
                ))
            })
            .collect()
    }
}

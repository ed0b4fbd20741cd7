//! Running an adaptation: crop the examples, fit the head, and put it in use when it beats the
//! shipped one. Its lease is extended while it works; it stops when cancelled, when its lease is
//! lost, at `--adapt-max-s`, and when the server shuts down.

use super::{AdaptExample, AdaptationStore, Lease};
use crate::roofs::classifier::head::{AdaptError, MIN_PER_CLASS, RoofHead, fit_head};
use crate::roofs::classifier::onnx::OnnxClassifier;
use crate::roofs::imagery::{Imagery, TileMemo, crop_footprint};
use crate::roofs::jobs::JobError;
use citymesh_core::roof_image::{Crop, RoofClass};
use std::sync::Arc;
use std::time::Duration;
use tokio_util::sync::CancellationToken;

/// Crops before the progress in the database is updated.
const PROGRESS_EVERY: usize = 16;

/// How adaptations run on this server.
#[derive(Debug, Clone)]
pub struct AdaptPolicy {
    /// Put a fitted head in use even when it does not beat the shipped head.
    pub accept_any: bool,
    /// The longest an adaptation may run.
    pub max_run: Duration,
    /// This process's lease on the adaptations it runs.
    pub lease: Lease,
}

impl AdaptPolicy {
    /// Whether a fitted head is put in use: its cross-validated accuracy beats the shipped
    /// head's on the same examples, or the operator allows any.
    pub fn accepts(&self, head: &RoofHead) -> bool {
        self.accept_any || head.report.accuracy > head.report.shipped_accuracy
    }
}

/// What an adaptation runs with: its store, the server's policy, the imagery and the shipped
/// model, and the server's stop (to say in the outcome that a shutdown stopped it).
pub struct AdaptationRun {
    pub store: AdaptationStore,
    pub policy: AdaptPolicy,
    pub imagery: Option<Arc<Imagery>>,
    pub base: Option<Arc<OnnxClassifier>>,
    pub server_stopping: CancellationToken,
}

/// Crops the examples and fits the head; records progress and the outcome in the store, and
/// answers the head to put in use when it is fitted and accepted (the caller puts it in use).
/// Never fails the caller (the outcome is in the store). Stops (within one crop or one fold's
/// fit) when `stop` is cancelled: by a client, by losing its lease, at `--adapt-max-s`, or by
/// the server's shutdown.
pub async fn run_adaptation(
    run: AdaptationRun,
    id: String,
    examples: Vec<AdaptExample>,
    stop: CancellationToken,
) -> Option<RoofHead> {
    let store = run.store.clone();
    let policy = run.policy.clone();
    let keeper = keep_lease(
        store.clone(),
        id.clone(),
        policy.lease.clone(),
        stop.clone(),
    );
    // Biased, the stop first: the work notices the stop too and ends with its own, vaguer
    // "stopped"; when both are ready, the outcome says why it stopped (the shutdown, a lost lease).
    let outcome = tokio::select! {
        biased;
        () = stop.cancelled() => Err(AdaptFailure::Failed(stopped_why(&run.server_stopping))),
        () = tokio::time::sleep(policy.max_run) => Err(AdaptFailure::Failed(format!(
            "stopped after {} s (--adapt-max-s): adapt on a smaller area",
            policy.max_run.as_secs_f64()
        ))),
        outcome = adapt(&run, &store, &id, examples, &stop) => outcome,
    };
    // Ends the lease keeper and any fitting still running on the blocking pool.
    stop.cancel();
    let _ = keeper.await;
    let in_use = outcome.as_ref().is_ok_and(|h| policy.accepts(h));
    match store.record(&id, &outcome, in_use).await {
        Ok(true) => {}
        Ok(false) => {
            tracing::info!(adaptation = %id, "adaptation ended before its outcome (cancelled)");
            return None;
        }
        Err(e) => {
            tracing::warn!(adaptation = %id, error = %e, "cannot store the adaptation's outcome");
            return None;
        }
    }
    match outcome {
        Ok(head) if in_use => Some(head),
        Ok(head) => {
            tracing::info!(adaptation = %id, head = %head.id(),
                accuracy = head.report.accuracy, shipped = head.report.shipped_accuracy,
                "adapted roof head not better than the shipped one: not used");
            None
        }
        Err(e) => {
            tracing::info!(adaptation = %id, error = %e, "adaptation ended without a head");
            None
        }
    }
}

/// Why an adaptation's stop was cancelled, as its outcome says (when not cancelled by a client,
/// whose cancel is already recorded).
fn stopped_why(server_stopping: &CancellationToken) -> String {
    if server_stopping.is_cancelled() {
        "stopped by the server's shutdown; ask again".to_owned()
    } else {
        "stopped: its lease was lost or it was cancelled".to_owned()
    }
}

/// Extends the lease every third of its length until `stop`; cancels `stop` when the lease is
/// lost (the adaptation was cancelled, or failed by another replica).
fn keep_lease(
    store: AdaptationStore,
    id: String,
    lease: Lease,
    stop: CancellationToken,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let every = lease.duration / 3;
        loop {
            tokio::select! {
                () = stop.cancelled() => return,
                () = tokio::time::sleep(every) => {}
            }
            match store.extend(&id, &lease).await {
                Ok(true) => {}
                Ok(false) => {
                    stop.cancel();
                    return;
                }
                Err(e) => tracing::warn!(adaptation = %id, error = %e, "cannot extend the lease"),
            }
        }
    })
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
    run: &AdaptationRun,
    store: &AdaptationStore,
    id: &str,
    examples: Vec<AdaptExample>,
    stop: &CancellationToken,
) -> Result<RoofHead, AdaptFailure> {
    let (Some(imagery), Some(base)) = (run.imagery.clone(), run.base.clone()) else {
        return Err(AdaptFailure::Failed(
            "no classifier or no imagery is configured".into(),
        ));
    };
    let progress = Progress::Store(store, id);
    fit_on_imagery(&base, &imagery, &examples, &progress, stop).await
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
    stop: &CancellationToken,
) -> Result<RoofHead, AdaptFailure> {
    let failed = |e: &dyn std::fmt::Display| AdaptFailure::Failed(e.to_string());
    let stopped = || AdaptFailure::Failed("stopped before the head was fitted".to_owned());
    let mut tiles = TileMemo::new();
    let mut crops: Vec<Crop> = Vec::with_capacity(examples.len());
    let mut classes: Vec<RoofClass> = Vec::with_capacity(examples.len());
    let mut crop_failed = 0usize;
    for (i, example) in examples.iter().enumerate() {
        if stop.is_cancelled() {
            return Err(stopped());
        }
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
    let stop = stop.clone();
    let fitted = tokio::task::spawn_blocking(move || {
        fit_head(&base, &crops, &classes, &|| stop.is_cancelled())
    })
    .await
    .map_err(|e| failed(&e))?;
    match fitted {
        Ok(head) => Ok(head),
        Err(e @ AdaptError::TooFew { .. }) => Err(AdaptFailure::TooFew(format!(
            "{e} (at least {MIN_PER_CLASS} per class must be cropped from the imagery)"
        ))),
        Err(AdaptError::Stopped) => Err(stopped()),
        Err(e) => Err(failed(&e)),
    }
}

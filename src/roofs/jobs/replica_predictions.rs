//! Predictions made by other replicas sharing one PostgreSQL: a job stored as done announces its
//! prediction in the same transaction (`postgres.rs`), and every replica puts it in its
//! [`super::PredictionIndex`], so `roofs=classified` tiles use it wherever the job ran. While
//! the listener is disconnected announcements are lost: each reconnection reloads the index.

use super::prediction_note::{PREDICTION_CHANNEL, PredictionNote};
use super::service::RoofJobs;
use crate::roofs::classifier::Prediction;
use sqlx::PgPool;
use sqlx::postgres::PgListener;
use std::sync::Arc;
use std::time::Duration;

/// Listens for predictions stored by any replica until the process ends; returns once
/// listening.
pub async fn listen(pool: PgPool, roofs: Arc<RoofJobs>) -> anyhow::Result<()> {
    let mut listener = connect(&pool).await?;
    tokio::spawn(async move {
        loop {
            match listener.try_recv().await {
                Ok(Some(n)) => match serde_json::from_str::<PredictionNote>(n.payload()) {
                    Ok(note) => heard(&roofs, note),
                    Err(e) => tracing::warn!("unreadable prediction announcement: {e}"),
                },
                Ok(None) => {
                    tracing::warn!("prediction listener reconnecting; reloading predictions");
                    reload(&roofs).await;
                }
                Err(e) => {
                    tracing::warn!("prediction listener failed ({e}); retrying in 1 s");
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    if let Ok(l) = connect(&pool).await {
                        listener = l;
                        reload(&roofs).await;
                    }
                }
            }
        }
    });
    Ok(())
}

fn heard(roofs: &RoofJobs, note: PredictionNote) {
    let active = roofs.active();
    if note.imagery_id == roofs.imagery_id && note.model_id == active.model_id {
        active.index.insert(
            note.osm_id,
            note.footprint_hash,
            Prediction::new(note.probabilities),
            note.work_ms,
        );
    }
}

async fn reload(roofs: &RoofJobs) {
    if let Err(e) = roofs.reload_predictions().await {
        tracing::warn!("cannot reload predictions: {e}");
    }
}

async fn connect(pool: &PgPool) -> anyhow::Result<PgListener> {
    let mut listener = PgListener::connect_with(pool).await?;
    listener.listen(PREDICTION_CHANNEL).await?;
    Ok(listener)
}

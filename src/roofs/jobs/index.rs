//! The predictions tiles use, in memory: for the served imagery and model, each building's latest
//! prediction with the footprint it was made for. Loaded from the job store at start-up and kept
//! current by the workers, so a tile request never queries SQLite for roofs.

use super::job::JobError;
use super::queue::JobQueue;
use crate::roofs::classifier::Prediction;
use std::collections::HashMap;
use std::sync::RwLock;

/// One building's prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexedPrediction {
    /// The footprint the prediction was made for ([`super::footprint_hash`]): a building whose
    /// outline changed since has no prediction until classified again.
    pub footprint_hash: String,
    pub prediction: Prediction,
    /// What making it took, milliseconds.
    pub work_ms: f64,
}

#[derive(Debug, Default)]
pub struct PredictionIndex {
    by_osm_id: RwLock<HashMap<String, IndexedPrediction>>,
}

impl PredictionIndex {
    /// Every stored prediction of `imagery_id` and `model_id`.
    pub async fn load(
        queue: &JobQueue,
        imagery_id: &str,
        model_id: &str,
    ) -> Result<Self, JobError> {
        let index = Self::default();
        for p in queue.predictions_of(imagery_id, model_id).await? {
            index.insert(p.osm_id, p.footprint_hash, p.prediction, p.work_ms);
        }
        Ok(index)
    }

    pub fn insert(
        &self,
        osm_id: String,
        footprint_hash: String,
        prediction: Prediction,
        work_ms: f64,
    ) {
        let entry = IndexedPrediction {
            footprint_hash,
            prediction,
            work_ms,
        };
        match self.by_osm_id.write() {
            Ok(mut map) => {
                map.insert(osm_id, entry);
            }
            Err(poisoned) => {
                poisoned.into_inner().insert(osm_id, entry);
            }
        }
    }

    /// Looks up several buildings under one lock.
    pub fn with<R>(&self, f: impl FnOnce(&HashMap<String, IndexedPrediction>) -> R) -> R {
        match self.by_osm_id.read() {
            Ok(map) => f(&map),
            Err(poisoned) => f(&poisoned.into_inner()),
        }
    }

    pub fn len(&self) -> usize {
        self.with(HashMap::len)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

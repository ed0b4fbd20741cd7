//! How a stored prediction is announced to other replicas sharing one PostgreSQL: the channel
//! and the note (`postgres.rs` sends it in the transaction that stores the job as done;
//! `replica_predictions.rs` hears it).

use serde::{Deserialize, Serialize};

/// The channel predictions are announced on.
pub const PREDICTION_CHANNEL: &str = "citymesh_prediction";

/// A stored prediction as announced (a few hundred bytes: the footprint stays in the table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredictionNote {
    pub osm_id: String,
    pub footprint_hash: String,
    pub imagery_id: String,
    pub model_id: String,
    pub probabilities: [f32; 3],
    pub work_ms: f64,
}

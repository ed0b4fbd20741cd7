//! The roof-shape classifier (docs/extensions.md section 1): a small CNN, trained on citymesh's own
//! renders (`training/roof_classifier/`), run with ONNX Runtime through `ort`.
//!
//! [`RoofClassifier`] is what the rest of citymesh calls; [`onnx`] implements it with a model file
//! and the runtime library that [`runtime`] finds; [`input`] turns any image into the model's
//! crop by the crop rule; [`training_set`] writes the synthetic training and test sets.

pub mod head;
pub mod input;
pub mod labelled;
pub mod onnx;
pub mod runtime;
pub mod training_set;

pub use onnx::Passes;

use citymesh_core::roof_image::{Crop, CropRule, RoofClass};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::Path;
use std::sync::Arc;

/// The committed model (training/roof_classifier/MODEL_CARD.md).
pub static MODEL: &[u8] = include_bytes!("../../../training/roof_classifier/roof_classifier.onnx");

/// The crop rule the committed model was trained with.
pub const MODEL_RULE: CropRule = CropRule::MODEL;

/// Why classification could not run.
#[derive(Debug, thiserror::Error)]
pub enum ClassifierError {
    /// Bad input: an unreadable image or file, a missing mask.
    #[error("{0}")]
    Input(String),
    /// ONNX Runtime is missing or could not be loaded.
    #[error("{0}")]
    Runtime(String),
    /// The model could not be loaded or run.
    #[error("roof model: {0}")]
    Model(String),
}

/// The model's answer for one crop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Prediction {
    /// Probability of each class, in [`RoofClass::ALL`] order; they sum to 1.
    pub probabilities: [f32; 3],
}

impl Prediction {
    pub fn new(probabilities: [f32; 3]) -> Self {
        Self { probabilities }
    }

    /// The most probable class (the first on a tie).
    pub fn class(&self) -> RoofClass {
        let mut best = 0;
        for i in 1..3 {
            if self.probabilities[i] > self.probabilities[best] {
                best = i;
            }
        }
        RoofClass::ALL[best]
    }

    /// The probability of the chosen class.
    pub fn confidence(&self) -> f32 {
        self.probabilities[self.class().index()]
    }
}

/// Classifies roof crops. Implementations are blocking and thread-safe; async code calls
/// [`classify_blocking`].
pub trait RoofClassifier: Send + Sync {
    /// The sha256 of the model file, hex.
    fn model_id(&self) -> &str;
    /// The side of the crops the model takes, pixels.
    fn crop_size(&self) -> usize;
    /// One prediction per crop, in order. Batches internally.
    fn classify(&self, crops: &[Crop]) -> Result<Vec<Prediction>, ClassifierError>;
}

/// Runs [`RoofClassifier::classify`] on the blocking pool.
pub async fn classify_blocking(
    classifier: Arc<dyn RoofClassifier>,
    crops: Vec<Crop>,
) -> Result<Vec<Prediction>, ClassifierError> {
    tokio::task::spawn_blocking(move || classifier.classify(&crops))
        .await
        .map_err(|e| ClassifierError::Runtime(format!("classification task failed: {e}")))?
}

/// A model's id: the sha256 of its bytes, hex.
pub fn model_id_of(model: &[u8]) -> String {
    Sha256::digest(model)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Loads the classifier: ONNX Runtime from `library` (or where [`runtime::find_runtime_library`]
/// looks) and the model from `model` (or the committed one), running each crop in `passes`.
pub fn load_classifier(
    library: Option<&Path>,
    model: Option<&Path>,
    passes: onnx::Passes,
) -> Result<Arc<dyn RoofClassifier>, ClassifierError> {
    Ok(load_onnx(library, model, passes)?)
}

/// [`load_classifier`], with the fitted head in `head` (a `citymesh adapt-roofs` file) in place
/// of the shipped one when given.
pub fn load_classifier_with_head(
    library: Option<&Path>,
    model: Option<&Path>,
    passes: onnx::Passes,
    head: Option<&Path>,
) -> Result<Arc<dyn RoofClassifier>, ClassifierError> {
    let base = load_onnx(library, model, passes)?;
    match head {
        Some(path) => Ok(Arc::new(head::HeadedClassifier::new(
            base,
            head::RoofHead::read(path)?,
        )?)),
        None => Ok(base),
    }
}

/// The ONNX classifier itself (for embeddings).
pub fn load_onnx(
    library: Option<&Path>,
    model: Option<&Path>,
    passes: onnx::Passes,
) -> Result<Arc<onnx::OnnxClassifier>, ClassifierError> {
    let library = runtime::find_runtime_library(library)?;
    let bytes = match model {
        Some(path) => std::fs::read(path)
            .map_err(|e| ClassifierError::Model(format!("{}: {e}", path.display())))?,
        None => MODEL.to_vec(),
    };
    Ok(Arc::new(onnx::OnnxClassifier::load(
        &library,
        &bytes,
        MODEL_RULE.size,
        passes,
    )?))
}

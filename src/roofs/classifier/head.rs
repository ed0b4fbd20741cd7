//! Roof-classifier heads fitted on the model's embeddings: the adaptation of the classifier to
//! one imagery source from labelled examples of it (docs/extensions.md section 3). A head is a
//! multinomial logistic regression on the `embedding` output, fitted in seconds with the turns
//! and flips of every example as augmentation, cross-validated, and written as a JSON file.

use super::onnx::{Embedded, OnnxClassifier};
use super::{ClassifierError, Prediction, RoofClassifier};
use citymesh_core::learn::cross_validation::cross_validate_with;
use citymesh_core::learn::cross_validation::{argmax, fit_examples, predict_example};
use citymesh_core::learn::{CrossValidation, Example, FitOptions, SoftmaxRegression};
use citymesh_core::roof_image::{Crop, RoofClass};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::sync::Arc;

/// The format tag of a head file.
pub const FORMAT: &str = "citymesh-roof-head/1";
/// Fewest examples per class a head is fitted from; with fewer the shipped head stays.
pub const MIN_PER_CLASS: usize = 20;
/// Folds of the cross-validation.
pub const FOLDS: usize = 5;
/// The precision the threshold is chosen for: the least top probability at which the
/// out-of-fold predictions above it are right this often.
pub const TARGET_PRECISION: f64 = 0.9;
/// Crops embedded between two checks for a stop.
const EMBED_CHUNK: usize = 32;
/// Largest head file read (bytes).
const MAX_HEAD_BYTES: u64 = 16 << 20;

/// How a head was fitted and how well it did out of fold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AdaptReport {
    /// Examples per class (flat, gabled, hipped).
    pub examples: [usize; 3],
    /// Out-of-fold accuracy of the new head.
    pub accuracy: f64,
    /// Out-of-fold confusion matrix, rows the truth.
    pub confusion: Vec<Vec<usize>>,
    /// Out-of-fold accuracy of the shipped head on the same examples, for comparison.
    pub shipped_accuracy: f64,
    /// The threshold chosen for this head, with the out-of-fold precision of the predictions
    /// at or above it and their share of all examples.
    pub threshold: Threshold,
}

/// A probability threshold and what it gives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Threshold {
    pub probability: f32,
    pub precision: f64,
    pub share: f64,
}

/// A fitted head for one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoofHead {
    pub format: String,
    /// The model whose embeddings it reads.
    pub model_id: String,
    pub classes: Vec<String>,
    pub regression: SoftmaxRegression,
    pub report: AdaptReport,
}

/// Why no head was fitted.
#[derive(Debug, thiserror::Error)]
pub enum AdaptError {
    #[error(
        "too few examples: {have:?} (flat, gabled, hipped); at least {MIN_PER_CLASS} per class are needed, so the shipped head stays"
    )]
    TooFew { have: [usize; 3] },
    #[error("{0}")]
    Classifier(#[from] ClassifierError),
    #[error("the fit failed: {0}")]
    Fit(String),
    #[error("stopped before the head was fitted")]
    Stopped,
}

impl RoofHead {
    /// The head's id: the sha256 of its model id and weights, hex (first 16 digits).
    pub fn id(&self) -> String {
        let mut h = Sha256::new();
        h.update(self.model_id.as_bytes());
        for v in self
            .regression
            .mean
            .iter()
            .chain(&self.regression.scale)
            .chain(&self.regression.weights)
            .chain(&self.regression.bias)
        {
            h.update(v.to_le_bytes());
        }
        h.finalize()[..8]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    }

    /// The probabilities of one crop from the embeddings of its passes.
    pub fn predict(&self, embeddings: &[Vec<f32>]) -> Option<Prediction> {
        let p = predict_example(&self.regression, embeddings)?;
        Some(Prediction::new([p[0], p[1], p[2]]))
    }

    pub fn read(path: &Path) -> Result<Self, ClassifierError> {
        let bytes = super::labelled::read_limited(path)?;
        if bytes.len() as u64 > MAX_HEAD_BYTES {
            return Err(ClassifierError::Input(format!(
                "{}: a head file is at most {} MiB",
                path.display(),
                MAX_HEAD_BYTES >> 20
            )));
        }
        let head: Self = serde_json::from_slice(&bytes).map_err(|e| {
            ClassifierError::Input(format!("{}: not a roof head: {e}", path.display()))
        })?;
        if head.format != FORMAT
            || head.regression.classes != 3
            || !head.regression.is_well_formed()
        {
            return Err(ClassifierError::Input(format!(
                "{}: not a well-formed {FORMAT} file",
                path.display()
            )));
        }
        Ok(head)
    }

    pub fn write(&self, path: &Path) -> Result<(), ClassifierError> {
        let text = serde_json::to_string(self)
            .map_err(|e| ClassifierError::Input(format!("head: {e}")))?;
        std::fs::write(path, text)
            .map_err(|e| ClassifierError::Input(format!("{}: {e}", path.display())))
    }
}

/// Fits a head on labelled crops: embeds them (every pass), cross-validates, chooses the
/// threshold out of fold, and fits the final head on all of them. Blocking; seconds for a few
/// hundred crops. `stop` is asked between batches of crops and between fits: once it answers
/// true, the fit ends with [`AdaptError::Stopped`].
pub fn fit_head(
    classifier: &OnnxClassifier,
    crops: &[Crop],
    classes: &[RoofClass],
    stop: &dyn Fn() -> bool,
) -> Result<RoofHead, AdaptError> {
    let mut have = [0usize; 3];
    classes.iter().for_each(|c| have[c.index()] += 1);
    if have.iter().any(|&n| n < MIN_PER_CLASS) {
        return Err(AdaptError::TooFew { have });
    }
    let mut embedded: Vec<Embedded> = Vec::with_capacity(crops.len());
    for chunk in crops.chunks(EMBED_CHUNK) {
        if stop() {
            return Err(AdaptError::Stopped);
        }
        embedded.extend(classifier.classify_embedded(chunk)?);
    }
    let shipped_right = embedded
        .iter()
        .zip(classes)
        .filter(|(e, c)| e.prediction.class() == **c)
        .count();
    let examples: Vec<Example> = embedded
        .into_iter()
        .zip(classes)
        .map(|(e, class)| Example {
            rows: e.embeddings,
            label: class.index(),
        })
        .collect();
    let options = FitOptions::default();
    let fit = |train: &[&Example]| {
        if stop() {
            return None;
        }
        fit_examples(train, 3, options)
    };
    let cv: Option<CrossValidation> =
        cross_validate_with(&examples, 3, FOLDS, fit, predict_example);
    if stop() {
        return Err(AdaptError::Stopped);
    }
    let cv = cv.ok_or_else(|| AdaptError::Fit("cross-validation failed".into()))?;
    let labels: Vec<usize> = examples.iter().map(|e| e.label).collect();
    let threshold = choose_threshold(&cv.probabilities, &labels, TARGET_PRECISION);
    let all: Vec<&Example> = examples.iter().collect();
    if stop() {
        return Err(AdaptError::Stopped);
    }
    let regression = fit_examples(&all, 3, options)
        .ok_or_else(|| AdaptError::Fit("the final fit failed".into()))?;
    Ok(RoofHead {
        format: FORMAT.into(),
        model_id: classifier.model_id().to_owned(),
        classes: RoofClass::ALL.iter().map(|c| c.name().to_owned()).collect(),
        regression,
        report: AdaptReport {
            examples: have,
            accuracy: cv.accuracy,
            confusion: cv.confusion,
            shipped_accuracy: shipped_right as f64 / examples.len() as f64,
            threshold,
        },
    })
}

/// The least probability in 0.34, 0.35, ... 0.99 at which the predictions at or above it are
/// right at least `target` of the time, with that precision and their share; the best
/// precision reached when none does.
pub fn choose_threshold(probabilities: &[Vec<f32>], labels: &[usize], target: f64) -> Threshold {
    let at = |t: f32| {
        let (mut kept, mut right) = (0usize, 0usize);
        for (p, &l) in probabilities.iter().zip(labels) {
            let best = argmax(p);
            if p[best] >= t {
                kept += 1;
                right += usize::from(best == l);
            }
        }
        Threshold {
            probability: t,
            precision: if kept == 0 {
                0.0
            } else {
                right as f64 / kept as f64
            },
            share: kept as f64 / probabilities.len().max(1) as f64,
        }
    };
    let grid: Vec<Threshold> = (34..=99).map(|i| at(i as f32 / 100.0)).collect();
    grid.iter()
        .find(|t| t.precision >= target)
        .copied()
        .or_else(|| {
            grid.iter()
                .copied()
                .max_by(|a, b| a.precision.total_cmp(&b.precision))
        })
        .unwrap_or(at(0.5))
}

/// The classifier with a fitted head in place of the shipped one.
pub struct HeadedClassifier {
    base: Arc<OnnxClassifier>,
    head: RoofHead,
    id: String,
}

impl HeadedClassifier {
    /// Fails when the head was fitted for another model.
    pub fn new(base: Arc<OnnxClassifier>, head: RoofHead) -> Result<Self, ClassifierError> {
        if head.model_id != base.model_id() {
            return Err(ClassifierError::Input(format!(
                "the head was fitted for model {}, not the loaded {}",
                head.model_id,
                base.model_id()
            )));
        }
        let id = format!("{}+head-{}", base.model_id(), head.id());
        Ok(Self { base, head, id })
    }
}

impl RoofClassifier for HeadedClassifier {
    /// The model's id and the head's: predictions made with a head are never mixed with the
    /// shipped head's.
    fn model_id(&self) -> &str {
        &self.id
    }

    fn crop_size(&self) -> usize {
        self.base.crop_size()
    }

    fn classify(&self, crops: &[Crop]) -> Result<Vec<Prediction>, ClassifierError> {
        self.base
            .classify_embedded(crops)?
            .iter()
            .map(|e| {
                self.head.predict(&e.embeddings).ok_or_else(|| {
                    ClassifierError::Model("the head does not fit the model's embedding".into())
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_is_the_least_probability_reaching_the_precision() {
        // Right at 0.9 and 0.8, wrong at 0.5 and 0.45, right at 0.4.
        let probs = vec![
            vec![0.9, 0.05, 0.05],
            vec![0.1, 0.8, 0.1],
            vec![0.5, 0.3, 0.2],
            vec![0.45, 0.3, 0.25],
            vec![0.4, 0.3, 0.3],
        ];
        let labels = [0, 1, 1, 2, 0];
        let t = choose_threshold(&probs, &labels, 0.9);
        assert_eq!(t.probability, 0.51);
        assert_eq!((t.precision, t.share), (1.0, 0.4));
        let t = choose_threshold(&probs, &labels, 0.6);
        assert_eq!(t.probability, 0.34);
        assert_eq!(t.precision, 0.6);
    }
}

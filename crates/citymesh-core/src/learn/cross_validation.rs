//! Stratified k-fold cross-validation (of [`SoftmaxRegression`] or any learner) on examples that each hold several
//! rows (a building seen in several turns and flips): rows of one example never fall on both
//! sides of a fold, and an example's prediction is the mean of its rows' probabilities.

use super::softmax_regression::{FitOptions, SoftmaxRegression};
use serde::Serialize;

/// One labelled example: its rows (e.g. the embeddings of a crop's turns and flips).
#[derive(Debug, Clone, PartialEq)]
pub struct Example {
    pub rows: Vec<Vec<f32>>,
    pub label: usize,
}

/// Out-of-fold results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossValidation {
    pub folds: usize,
    pub examples: usize,
    /// Examples predicted right.
    pub correct: usize,
    pub accuracy: f64,
    /// `confusion[truth][predicted]`.
    pub confusion: Vec<Vec<usize>>,
    /// Each example's out-of-fold probabilities, in input order.
    #[serde(skip)]
    pub probabilities: Vec<Vec<f32>>,
}

/// Fits on all examples' rows.
pub fn fit_examples(
    examples: &[&Example],
    classes: usize,
    options: FitOptions,
) -> Option<SoftmaxRegression> {
    let rows: Vec<&[f32]> = examples
        .iter()
        .flat_map(|e| e.rows.iter().map(Vec::as_slice))
        .collect();
    let labels: Vec<usize> = examples
        .iter()
        .flat_map(|e| std::iter::repeat_n(e.label, e.rows.len()))
        .collect();
    SoftmaxRegression::fit(&rows, &labels, classes, options)
}

/// The mean of the model's probabilities over an example's rows.
pub fn predict_example(model: &SoftmaxRegression, rows: &[Vec<f32>]) -> Option<Vec<f32>> {
    let mut mean = vec![0.0f32; model.classes];
    for r in rows {
        let p = model.probabilities(r)?;
        for (m, v) in mean.iter_mut().zip(p) {
            *m += v / rows.len() as f32;
        }
    }
    (!rows.is_empty()).then_some(mean)
}

/// Stratified `folds`-fold cross-validation of [`SoftmaxRegression`]: the examples of each class
/// are dealt to the folds in turn, in input order. `None` when fewer than 2 folds or a fit fails.
pub fn cross_validate(
    examples: &[Example],
    classes: usize,
    folds: usize,
    options: FitOptions,
) -> Option<CrossValidation> {
    cross_validate_with(
        examples,
        classes,
        folds,
        |train| fit_examples(train, classes, options),
        predict_example,
    )
}

/// Stratified `folds`-fold cross-validation of any learner: `fit` makes a model of the training
/// examples, `predict` gives an example's probabilities. The examples of each class are dealt to
/// the folds in turn, in input order. `None` when fewer than 2 folds or a fit fails.
pub fn cross_validate_with<M>(
    examples: &[Example],
    classes: usize,
    folds: usize,
    fit: impl Fn(&[&Example]) -> Option<M>,
    predict: impl Fn(&M, &[Vec<f32>]) -> Option<Vec<f32>>,
) -> Option<CrossValidation> {
    if folds < 2 || examples.len() < folds || classes == 0 {
        return None;
    }
    let mut seen = vec![0usize; classes];
    let fold_of: Vec<usize> = examples
        .iter()
        .map(|e| {
            let f = seen.get(e.label).copied().unwrap_or(0) % folds;
            if let Some(s) = seen.get_mut(e.label) {
                *s += 1;
            }
            f
        })
        .collect();
    let mut probabilities = vec![Vec::new(); examples.len()];
    for f in 0..folds {
        let train: Vec<&Example> = examples
            .iter()
            .zip(&fold_of)
            .filter(|(_, g)| **g != f)
            .map(|(e, _)| e)
            .collect();
        let model = fit(&train)?;
        for (i, e) in examples.iter().enumerate() {
            if fold_of[i] == f {
                probabilities[i] = predict(&model, &e.rows)?;
            }
        }
    }
    let mut confusion = vec![vec![0usize; classes]; classes];
    for (e, p) in examples.iter().zip(&probabilities) {
        confusion[e.label.min(classes - 1)][argmax(p).min(classes - 1)] += 1;
    }
    let correct = (0..classes).map(|c| confusion[c][c]).sum();
    Some(CrossValidation {
        folds,
        examples: examples.len(),
        correct,
        accuracy: correct as f64 / examples.len() as f64,
        confusion,
        probabilities,
    })
}

/// The index of the largest value (the first on a tie).
pub fn argmax(p: &[f32]) -> usize {
    let mut best = 0;
    for i in 1..p.len() {
        if p[i] > p[best] {
            best = i;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example(label: usize, i: usize) -> Example {
        let base = [[0.0f32, 0.0], [4.0, 0.0], [0.0, 4.0]][label];
        let j = i as f32 * 0.05;
        Example {
            rows: vec![vec![base[0] + j, base[1]], vec![base[0], base[1] + j]],
            label,
        }
    }

    #[test]
    fn separable_examples_are_all_right_out_of_fold() {
        let examples: Vec<Example> = (0..30).map(|i| example(i % 3, i)).collect();
        let cv = cross_validate(&examples, 3, 5, FitOptions::default()).unwrap();
        assert_eq!((cv.examples, cv.correct, cv.folds), (30, 30, 5));
        assert_eq!(
            cv.confusion,
            vec![vec![10, 0, 0], vec![0, 10, 0], vec![0, 0, 10]]
        );
        assert_eq!(cv.probabilities.len(), 30);
    }

    #[test]
    fn too_few_examples_give_no_cross_validation() {
        let examples: Vec<Example> = (0..3).map(|i| example(i % 3, i)).collect();
        assert!(cross_validate(&examples, 3, 5, FitOptions::default()).is_none());
        assert!(cross_validate(&examples, 3, 1, FitOptions::default()).is_none());
    }
}

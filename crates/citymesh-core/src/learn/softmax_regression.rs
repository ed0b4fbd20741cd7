//! Multinomial logistic regression (softmax regression) with L2 regularisation and class
//! weights, fitted by full-batch Adam on standardised features. Deterministic: the same rows in
//! the same order give the same bits.

use serde::{Deserialize, Serialize};

/// How a model is fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// L2 penalty on the weights (not the biases), per row-averaged loss.
    pub l2: f64,
    /// Full-batch gradient steps.
    pub iterations: usize,
    /// Adam's step size.
    pub step: f64,
    /// Weigh each class by the inverse of its share of the rows, so a rare class counts as much
    /// as a common one.
    pub balanced: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            l2: 1e-2,
            iterations: 300,
            step: 0.05,
            balanced: true,
        }
    }
}

/// A fitted model: `p = softmax(W ((x - mean) / scale) + b)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SoftmaxRegression {
    pub classes: usize,
    pub dims: usize,
    pub mean: Vec<f32>,
    pub scale: Vec<f32>,
    /// `classes` rows of `dims` weights.
    pub weights: Vec<f32>,
    pub bias: Vec<f32>,
}

impl SoftmaxRegression {
    /// Fits on `rows` (each `dims` long) with labels in `0..classes`. `None` when there are no
    /// rows, their lengths differ, a label is out of range or a value is not finite.
    pub fn fit(
        rows: &[&[f32]],
        labels: &[usize],
        classes: usize,
        options: FitOptions,
    ) -> Option<Self> {
        let n = rows.len();
        let dims = rows.first()?.len();
        if n != labels.len()
            || classes < 2
            || dims == 0
            || rows
                .iter()
                .any(|r| r.len() != dims || r.iter().any(|v| !v.is_finite()))
            || labels.iter().any(|&l| l >= classes)
        {
            return None;
        }
        // Standardise: mean 0, unit variance per feature (constant features keep scale 1).
        let mut mean = vec![0.0f64; dims];
        for r in rows {
            for (m, &v) in mean.iter_mut().zip(r.iter()) {
                *m += f64::from(v);
            }
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let mut var = vec![0.0f64; dims];
        for r in rows {
            for ((s, &v), m) in var.iter_mut().zip(r.iter()).zip(&mean) {
                *s += (f64::from(v) - m).powi(2);
            }
        }
        let scale: Vec<f64> = var
            .iter()
            .map(|s| {
                let sd = (s / n as f64).sqrt();
                if sd > 1e-6 { sd } else { 1.0 }
            })
            .collect();
        let x: Vec<f64> = rows
            .iter()
            .flat_map(|r| {
                r.iter()
                    .zip(&mean)
                    .zip(&scale)
                    .map(|((&v, m), s)| (f64::from(v) - m) / s)
            })
            .collect();
        // Row weights: balanced classes, normalised to sum to 1.
        let mut count = vec![0usize; classes];
        labels.iter().for_each(|&l| count[l] += 1);
        let present = count.iter().filter(|&&c| c > 0).count().max(1);
        let row_weight: Vec<f64> = labels
            .iter()
            .map(|&l| {
                if options.balanced {
                    1.0 / (present as f64 * count[l] as f64)
                } else {
                    1.0 / n as f64
                }
            })
            .collect();
        let k = classes;
        let mut w = vec![0.0f64; k * dims];
        let mut b = vec![0.0f64; k];
        let (mut mw, mut vw) = (vec![0.0f64; k * dims], vec![0.0f64; k * dims]);
        let (mut mb, mut vb) = (vec![0.0f64; k], vec![0.0f64; k]);
        let (beta1, beta2, eps) = (0.9f64, 0.999f64, 1e-8f64);
        let mut gw = vec![0.0f64; k * dims];
        let mut gb = vec![0.0f64; k];
        let mut logits = vec![0.0f64; k];
        for t in 1..=options.iterations {
            gw.iter_mut().for_each(|g| *g = 0.0);
            gb.iter_mut().for_each(|g| *g = 0.0);
            for i in 0..n {
                let xi = &x[i * dims..(i + 1) * dims];
                for c in 0..k {
                    logits[c] = b[c] + dot(&w[c * dims..(c + 1) * dims], xi);
                }
                softmax_in_place(&mut logits);
                for c in 0..k {
                    let err = (logits[c] - f64::from(u8::from(labels[i] == c))) * row_weight[i];
                    gb[c] += err;
                    for (g, &v) in gw[c * dims..(c + 1) * dims].iter_mut().zip(xi) {
                        *g += err * v;
                    }
                }
            }
            for (g, &wv) in gw.iter_mut().zip(&w) {
                *g += options.l2 * wv;
            }
            let (c1, c2) = (1.0 - beta1.powi(t as i32), 1.0 - beta2.powi(t as i32));
            let adam = |p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64]| {
                for j in 0..p.len() {
                    m[j] = beta1 * m[j] + (1.0 - beta1) * g[j];
                    v[j] = beta2 * v[j] + (1.0 - beta2) * g[j] * g[j];
                    p[j] -= options.step * (m[j] / c1) / ((v[j] / c2).sqrt() + eps);
                }
            };
            adam(&mut w, &gw, &mut mw, &mut vw);
            adam(&mut b, &gb, &mut mb, &mut vb);
        }
        Some(Self {
            classes,
            dims,
            mean: mean.iter().map(|&v| v as f32).collect(),
            scale: scale.iter().map(|&v| v as f32).collect(),
            weights: w.iter().map(|&v| v as f32).collect(),
            bias: b.iter().map(|&v| v as f32).collect(),
        })
    }

    /// Class probabilities of one row; `None` when its length is not `dims` or the model is
    /// malformed (as one read from a file may be).
    pub fn probabilities(&self, row: &[f32]) -> Option<Vec<f32>> {
        if row.len() != self.dims || !self.is_well_formed() {
            return None;
        }
        let mut logits: Vec<f64> = (0..self.classes)
            .map(|c| {
                let w = &self.weights[c * self.dims..(c + 1) * self.dims];
                let mut s = f64::from(self.bias[c]);
                for j in 0..self.dims {
                    let z =
                        (f64::from(row[j]) - f64::from(self.mean[j])) / f64::from(self.scale[j]);
                    s += f64::from(w[j]) * z;
                }
                s
            })
            .collect();
        softmax_in_place(&mut logits);
        Some(logits.iter().map(|&p| p as f32).collect())
    }

    /// Whether the vectors have the lengths `classes` and `dims` say and every value is finite
    /// (scales non-zero).
    pub fn is_well_formed(&self) -> bool {
        self.classes >= 2
            && self.mean.len() == self.dims
            && self.scale.len() == self.dims
            && self.classes.checked_mul(self.dims) == Some(self.weights.len())
            && self.bias.len() == self.classes
            && self.scale.iter().all(|s| s.is_finite() && *s != 0.0)
            && self
                .mean
                .iter()
                .chain(&self.weights)
                .chain(&self.bias)
                .all(|v| v.is_finite())
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn softmax_in_place(v: &mut [f64]) {
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut sum = 0.0;
    for x in v.iter_mut() {
        *x = (*x - max).exp();
        sum += *x;
    }
    v.iter_mut().for_each(|x| *x /= sum);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn separable_classes_are_learned_exactly() {
        // Three clusters along two axes.
        let rows: Vec<Vec<f32>> = (0..30)
            .map(|i| {
                let c = i % 3;
                let jitter = (i / 3) as f32 * 0.01;
                match c {
                    0 => vec![0.0 + jitter, 0.0],
                    1 => vec![5.0 + jitter, 0.0],
                    _ => vec![0.0, 5.0 + jitter],
                }
            })
            .collect();
        let labels: Vec<usize> = (0..30).map(|i| i % 3).collect();
        let refs: Vec<&[f32]> = rows.iter().map(Vec::as_slice).collect();
        let m = SoftmaxRegression::fit(&refs, &labels, 3, FitOptions::default()).unwrap();
        for (r, &l) in rows.iter().zip(&labels) {
            let p = m.probabilities(r).unwrap();
            let best = (0..3).max_by(|&a, &b| p[a].total_cmp(&p[b])).unwrap();
            assert_eq!(best, l, "{p:?}");
            assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
        assert_eq!(m.probabilities(&[1.0]), None);
    }

    #[test]
    fn bad_input_fits_nothing() {
        let a = [1.0f32, 2.0];
        let b = [1.0f32];
        let nan = [f32::NAN, 0.0];
        assert!(SoftmaxRegression::fit(&[&a, &b], &[0, 1], 3, FitOptions::default()).is_none());
        assert!(SoftmaxRegression::fit(&[&a], &[3], 3, FitOptions::default()).is_none());
        assert!(SoftmaxRegression::fit(&[&nan], &[0], 3, FitOptions::default()).is_none());
        assert!(SoftmaxRegression::fit(&[], &[], 3, FitOptions::default()).is_none());
    }

    proptest! {
        #[test]
        fn probabilities_are_a_distribution_and_fits_repeat(
            values in proptest::collection::vec(-100.0f32..100.0, 12..60)
        ) {
            let rows: Vec<&[f32]> = values.chunks_exact(4).collect();
            let labels: Vec<usize> = (0..rows.len()).map(|i| i % 3).collect();
            let options = FitOptions { iterations: 20, ..FitOptions::default() };
            let a = SoftmaxRegression::fit(&rows, &labels, 3, options).unwrap();
            let b = SoftmaxRegression::fit(&rows, &labels, 3, options).unwrap();
            prop_assert_eq!(&a, &b);
            for r in &rows {
                let p = a.probabilities(r).unwrap();
                prop_assert!(p.iter().all(|v| (0.0..=1.0).contains(v)));
                prop_assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-4);
            }
        }
    }
}

//! Gradient-boosted decision trees for a few classes (multinomial deviance, Newton steps), on
//! features binned at their quantiles. Deterministic: no sampling, ties go to the first feature
//! and the first cut, so the same rows in the same order give the same bits.

use serde::Serialize;

/// How a model is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoostOptions {
    /// Boosting rounds (one tree per class each).
    pub rounds: usize,
    /// Levels of splits per tree.
    pub depth: usize,
    /// Shrinkage of each tree's leaf values.
    pub learning_rate: f32,
    /// L2 penalty on leaf values (added to the hessian sum).
    pub lambda: f32,
    /// Fewest rows on each side of a split.
    pub min_leaf_rows: usize,
    /// Most cut points per feature (quantiles of its values).
    pub max_cuts: usize,
}

impl Default for BoostOptions {
    fn default() -> Self {
        Self {
            rounds: 120,
            depth: 3,
            learning_rate: 0.08,
            lambda: 1.0,
            min_leaf_rows: 6,
            max_cuts: 32,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Node {
    /// Rows with `value <= cut` go to `left`, the rest (and NaN) to `left + 1`.
    Split {
        feature: u32,
        cut: f32,
        left: u32,
    },
    Leaf(f32),
}

#[derive(Debug, Clone, PartialEq)]
struct Tree {
    nodes: Vec<Node>,
}

impl Tree {
    fn value(&self, row: &[f32]) -> f32 {
        let mut i = 0usize;
        loop {
            match self.nodes[i] {
                Node::Leaf(v) => return v,
                Node::Split { feature, cut, left } => {
                    let x = row.get(feature as usize).copied().unwrap_or(f32::NAN);
                    i = if x <= cut {
                        left as usize
                    } else {
                        left as usize + 1
                    };
                }
            }
        }
    }
}

/// A fitted model: per class, a base score plus the sum of its trees; softmax over classes.
#[derive(Debug, Clone, PartialEq)]
pub struct BoostedTrees {
    pub classes: usize,
    pub dims: usize,
    base: Vec<f32>,
    /// Round-major: `trees[round * classes + class]`.
    trees: Vec<Tree>,
}

/// One feature's cut points and each row's bin (`bin b` holds values in `(cut[b-1], cut[b]]`).
struct BinnedFeature {
    cuts: Vec<f32>,
    bins: Vec<u8>,
}

fn bin_feature(values: &[f32], max_cuts: usize) -> BinnedFeature {
    let mut sorted: Vec<f32> = values.to_vec();
    sorted.sort_by(f32::total_cmp);
    sorted.dedup();
    let max_cuts = max_cuts.clamp(1, 255);
    let cuts: Vec<f32> = if sorted.len() <= max_cuts + 1 {
        // Every distinct value but the largest is a cut.
        sorted[..sorted.len().saturating_sub(1)].to_vec()
    } else {
        let mut c: Vec<f32> = (1..=max_cuts)
            .map(|q| sorted[q * (sorted.len() - 1) / (max_cuts + 1)])
            .collect();
        c.dedup();
        c
    };
    // Missing values are binned as +inf: above every cut, as prediction sends NaN right.
    let cuts: Vec<f32> = cuts.into_iter().filter(|c| c.is_finite()).collect();
    let bins = values
        .iter()
        .map(|v| cuts.partition_point(|c| c < v) as u8)
        .collect();
    BinnedFeature { cuts, bins }
}

#[derive(Clone, Copy, Default)]
struct Sums {
    g: f64,
    h: f64,
    n: usize,
}

impl Sums {
    fn add(&mut self, g: f64, h: f64) {
        self.g += g;
        self.h += h;
        self.n += 1;
    }
    fn score(&self, lambda: f64) -> f64 {
        self.g * self.g / (self.h + lambda)
    }
}

struct Grower<'a> {
    features: &'a [BinnedFeature],
    grad: &'a [f64],
    hess: &'a [f64],
    options: BoostOptions,
}

impl Grower<'_> {
    /// Grows the subtree over `rows` at `depth` into `nodes`, at index `at` (already pushed).
    fn grow(&self, rows: &[u32], depth: usize, nodes: &mut Vec<Node>, at: usize) {
        let lambda = f64::from(self.options.lambda);
        let mut total = Sums::default();
        for &r in rows {
            total.add(self.grad[r as usize], self.hess[r as usize]);
        }
        let leaf = (-total.g / (total.h + lambda)) as f32 * self.options.learning_rate;
        nodes[at] = Node::Leaf(leaf);
        if depth == 0 || rows.len() < 2 * self.options.min_leaf_rows {
            return;
        }
        let parent = total.score(lambda);
        let mut best: Option<(f64, usize, usize)> = None;
        let mut hist: Vec<Sums> = Vec::new();
        for (f, feature) in self.features.iter().enumerate() {
            if feature.cuts.is_empty() {
                continue;
            }
            hist.clear();
            hist.resize(feature.cuts.len() + 1, Sums::default());
            for &r in rows {
                let r = r as usize;
                hist[feature.bins[r] as usize].add(self.grad[r], self.hess[r]);
            }
            let mut left = Sums::default();
            for (b, bin) in hist.iter().enumerate().take(feature.cuts.len()) {
                left.g += bin.g;
                left.h += bin.h;
                left.n += bin.n;
                let right = Sums {
                    g: total.g - left.g,
                    h: total.h - left.h,
                    n: total.n - left.n,
                };
                if left.n < self.options.min_leaf_rows || right.n < self.options.min_leaf_rows {
                    continue;
                }
                let gain = left.score(lambda) + right.score(lambda) - parent;
                if gain > 1e-9 && best.is_none_or(|(g, _, _)| gain > g) {
                    best = Some((gain, f, b));
                }
            }
        }
        let Some((_, f, b)) = best else {
            return;
        };
        let feature = &self.features[f];
        let (left_rows, right_rows): (Vec<u32>, Vec<u32>) = rows
            .iter()
            .partition(|&&r| (feature.bins[r as usize] as usize) <= b);
        let left = nodes.len();
        nodes.push(Node::Leaf(0.0));
        nodes.push(Node::Leaf(0.0));
        nodes[at] = Node::Split {
            feature: f as u32,
            cut: feature.cuts[b],
            left: left as u32,
        };
        self.grow(&left_rows, depth - 1, nodes, left);
        self.grow(&right_rows, depth - 1, nodes, left + 1);
    }
}

fn softmax(scores: &mut [f32]) {
    let max = scores.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut sum = 0.0;
    for s in scores.iter_mut() {
        *s = (*s - max).exp();
        sum += *s;
    }
    for s in scores.iter_mut() {
        *s /= sum;
    }
}

impl BoostedTrees {
    /// Fits on `rows` (each `dims` long; NaN marks a missing value and goes right of every cut)
    /// with labels in `0..classes`. `None` when there are no rows, their lengths differ or a
    /// label is out of range.
    pub fn fit(
        rows: &[&[f32]],
        labels: &[usize],
        classes: usize,
        options: BoostOptions,
    ) -> Option<Self> {
        let n = rows.len();
        let dims = rows.first()?.len();
        if n != labels.len()
            || classes < 2
            || rows.iter().any(|r| r.len() != dims)
            || labels.iter().any(|&l| l >= classes)
            || n > u32::MAX as usize
        {
            return None;
        }
        let features: Vec<BinnedFeature> = (0..dims)
            .map(|d| {
                let column: Vec<f32> = rows
                    .iter()
                    .map(|r| if r[d].is_nan() { f32::INFINITY } else { r[d] })
                    .collect();
                bin_feature(&column, options.max_cuts)
            })
            .collect();
        // Base scores: the log of each class's share (smoothed).
        let mut counts = vec![1.0f32; classes];
        for &l in labels {
            counts[l] += 1.0;
        }
        let total: f32 = counts.iter().sum();
        let base: Vec<f32> = counts.iter().map(|c| (c / total).ln()).collect();
        let mut scores: Vec<f32> = (0..n).flat_map(|_| base.iter().copied()).collect();
        let all: Vec<u32> = (0..n as u32).collect();
        let mut trees = Vec::with_capacity(options.rounds * classes);
        let mut grad = vec![0.0f64; n];
        let mut hess = vec![0.0f64; n];
        let mut p = vec![0.0f32; classes];
        let mut probabilities = vec![0.0f32; n * classes];
        for _ in 0..options.rounds {
            for i in 0..n {
                p.copy_from_slice(&scores[i * classes..(i + 1) * classes]);
                softmax(&mut p);
                probabilities[i * classes..(i + 1) * classes].copy_from_slice(&p);
            }
            for k in 0..classes {
                for i in 0..n {
                    let pk = f64::from(probabilities[i * classes + k]);
                    let y = if labels[i] == k { 1.0 } else { 0.0 };
                    grad[i] = pk - y;
                    hess[i] = (pk * (1.0 - pk)).max(1e-6);
                }
                let grower = Grower {
                    features: &features,
                    grad: &grad,
                    hess: &hess,
                    options,
                };
                let mut nodes = vec![Node::Leaf(0.0)];
                grower.grow(&all, options.depth, &mut nodes, 0);
                let tree = Tree { nodes };
                for (i, row) in rows.iter().enumerate() {
                    scores[i * classes + k] += tree.value(row);
                }
                trees.push(tree);
            }
        }
        Some(Self {
            classes,
            dims,
            base,
            trees,
        })
    }

    /// The class probabilities of a row; `None` when its length is not the model's.
    pub fn probabilities(&self, row: &[f32]) -> Option<Vec<f32>> {
        if row.len() != self.dims {
            return None;
        }
        let mut scores = self.base.clone();
        for (t, tree) in self.trees.iter().enumerate() {
            scores[t % self.classes] += tree.value(row);
        }
        softmax(&mut scores);
        Some(scores)
    }

    /// Trees in the model.
    pub fn tree_count(&self) -> usize {
        self.trees.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows_of(v: &[Vec<f32>]) -> Vec<&[f32]> {
        v.iter().map(Vec::as_slice).collect()
    }

    #[test]
    fn learns_a_threshold_and_an_interaction() {
        // Class 0 when x < 5; class 1 when x >= 5 and y < 0.5; class 2 otherwise.
        let mut rows = Vec::new();
        let mut labels = Vec::new();
        for i in 0..200 {
            let x = (i % 10) as f32;
            let y = ((i / 10) % 2) as f32;
            rows.push(vec![x, y, (i % 7) as f32]);
            labels.push(if x < 5.0 {
                0
            } else if y < 0.5 {
                1
            } else {
                2
            });
        }
        let model =
            BoostedTrees::fit(&rows_of(&rows), &labels, 3, BoostOptions::default()).unwrap();
        for (r, &l) in rows.iter().zip(&labels) {
            let p = model.probabilities(r).unwrap();
            assert!((p.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            assert_eq!(crate::learn::cross_validation::argmax(&p), l, "{r:?} {p:?}");
            assert!(p[l] > 0.9, "{r:?} {p:?}");
        }
        assert_eq!(model.tree_count(), 3 * BoostOptions::default().rounds);
    }

    #[test]
    fn missing_values_are_split_on() {
        // Class 1 exactly where the first feature is missing.
        let rows: Vec<Vec<f32>> = (0..60)
            .map(|i| vec![if i % 3 == 0 { f32::NAN } else { i as f32 }])
            .collect();
        let labels: Vec<usize> = (0..60).map(|i| usize::from(i % 3 == 0)).collect();
        let model =
            BoostedTrees::fit(&rows_of(&rows), &labels, 2, BoostOptions::default()).unwrap();
        assert!(model.probabilities(&[f32::NAN]).unwrap()[1] > 0.9);
        assert!(model.probabilities(&[7.0]).unwrap()[0] > 0.9);
    }

    #[test]
    fn the_same_rows_give_the_same_bits_and_bad_input_is_refused() {
        let rows: Vec<Vec<f32>> = (0..50)
            .map(|i| vec![(i * 37 % 11) as f32, i as f32])
            .collect();
        let labels: Vec<usize> = (0..50).map(|i| (i * 37 % 11) % 3).collect();
        let a = BoostedTrees::fit(&rows_of(&rows), &labels, 3, BoostOptions::default()).unwrap();
        let b = BoostedTrees::fit(&rows_of(&rows), &labels, 3, BoostOptions::default()).unwrap();
        assert_eq!(a, b);
        assert!(BoostedTrees::fit(&[], &[], 3, BoostOptions::default()).is_none());
        assert!(BoostedTrees::fit(&rows_of(&rows), &labels, 2, BoostOptions::default()).is_none());
        assert_eq!(a.probabilities(&[1.0]), None);
    }

    #[test]
    fn binning_puts_each_value_at_or_below_its_cut() {
        let values: Vec<f32> = (0..1000).map(|i| (i % 97) as f32).collect();
        let b = bin_feature(&values, 8);
        assert!(b.cuts.len() <= 8 && !b.cuts.is_empty());
        for (v, &bin) in values.iter().zip(&b.bins) {
            let bin = bin as usize;
            if bin < b.cuts.len() {
                assert!(*v <= b.cuts[bin]);
            }
            if bin > 0 {
                assert!(*v > b.cuts[bin - 1]);
            }
        }
    }
}

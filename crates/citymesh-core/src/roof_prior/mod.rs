//! A roof prior learned from an area's own tags (docs/extensions.md section 4): the buildings that
//! carry `roof:shape` teach gradient-boosted trees ([`crate::learn::boosted_trees`]) to tell
//! flat, gabled and hipped roofs apart from each building's outline, its tags ([`features`]) and
//! the shapes tagged around it ([`neighbours`]); the trees then give every untagged building of
//! the area its class probabilities. The prior is cross-validated on the tagged buildings and
//! abstains when they are too few or it does not beat always answering their most common class.
//! Deterministic: the same records give the same prior and the same identity.

pub mod features;
pub mod neighbours;

use crate::building::roof::RoofShape;
use crate::geo::LocalFrame;
use crate::learn::boosted_trees::{BoostOptions, BoostedTrees};
use crate::learn::cross_validation::{Example, argmax, cross_validate_with};
use crate::osm::{BuildingRecord, OsmId};
use crate::roof_image::RoofClass;
use features::{Outline, own_feature_names, own_features};
use neighbours::{Neighbourhood, neighbour_feature_names};
use serde::Serialize;
use std::collections::HashMap;

/// Fewer tagged buildings (of the three classes) than this, and the prior abstains (its
/// predictions are still made and reported, but not applied).
pub const MIN_TAGGED: usize = 30;
/// Fewer tagged buildings than this, and no prediction is made at all (with at least this many,
/// predictions are made even when they are all of one class, but not applied).
pub const MIN_TO_FIT: usize = 10;
/// The prior abstains unless its cross-validated accuracy beats the share of the most common
/// tagged class by at least this much (0.05 = 5 percentage points), and by that share's standard
/// error (`sqrt(m (1 - m) / n)`), which is larger below about 100 tagged buildings: on few
/// examples an out-of-fold accuracy is too noisy to trust a small lead.
pub const MIN_MARGIN: f64 = 0.05;

/// The lead over the most common class's share `m` of `n` examples the trees must show.
pub fn required_margin(m: f64, n: usize) -> f64 {
    MIN_MARGIN.max((m * (1.0 - m) / n.max(1) as f64).sqrt())
}
/// A prediction is applied to a roof only at or above this probability; below it the roof keeps
/// the default (flat) and counts as uncertain.
pub const APPLY_THRESHOLD: f32 = 0.5;
/// At most this many tagged buildings are learned from (those whose ids hash lowest), which
/// bounds the cost of a fit (about a second on one core).
pub const MAX_EXAMPLES: usize = 5_000;
/// Folds of the cross-validation.
pub const FOLDS: usize = 5;
/// Changes whenever features or learner change, so identities change with them.
const VERSION: &str = "roof-prior-1";

/// The class a `roof:shape` value teaches, if any: `many` and `complex` roofs are drawn by their
/// parts and teach nothing.
pub fn tagged_class(record: &BuildingRecord) -> Option<RoofClass> {
    let value = record.tags.get("roof:shape")?.trim();
    if matches!(value, "many" | "complex") {
        return None;
    }
    RoofClass::of_shape(RoofShape::from_tag(value)?)
}

/// How the prior did on the tagged buildings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PriorReport {
    /// Buildings in the area (outlines that could be measured; parts left out).
    pub buildings: usize,
    /// Tagged buildings learned from (at most [`MAX_EXAMPLES`]).
    pub tagged: usize,
    /// Tagged buildings per class: flat, gabled, hipped.
    pub tagged_per_class: [usize; 3],
    /// Untagged buildings given probabilities.
    pub predicted: usize,
    /// Out-of-fold accuracy on the tagged buildings ([`FOLDS`] stratified folds).
    pub cross_validated_accuracy: Option<f64>,
    /// Tagged buildings predicted right out of fold.
    pub cross_validated_correct: Option<usize>,
    /// `confusion[truth][predicted]`, out of fold (flat, gabled, hipped).
    pub confusion: Option<Vec<Vec<usize>>>,
    /// The share of the most common tagged class: what always answering it would score.
    pub majority_share: f64,
    /// Why the prior is not applied, if it is not.
    pub abstained: Option<String>,
    /// What gives the predictions: `trees`, or `class_shares` (the tagged classes' shares,
    /// smoothed, the same for every building) when the trees do not beat the most common class
    /// by [`required_margin`] out of fold; `none` below [`MIN_TO_FIT`].
    pub predictor: &'static str,
    /// A digest of the training rows, their labels and the learner's settings.
    pub identity: String,
}

/// A fitted prior: its report and the probabilities of the area's untagged buildings.
#[derive(Debug, Clone)]
pub struct RoofPrior {
    pub report: PriorReport,
    probabilities: HashMap<OsmId, [f32; 3]>,
}

/// The names of a prior's feature columns, in order.
pub fn feature_names() -> Vec<String> {
    let mut names = own_feature_names();
    names.extend(neighbour_feature_names());
    names
}

impl RoofPrior {
    /// Learns from the tagged buildings among `records` and predicts the untagged ones. Parts and
    /// outlines without area are left out; records are taken in id order, each id once.
    pub fn fit(records: &[&BuildingRecord]) -> Self {
        Self::fit_with(records, BoostOptions::default())
    }

    /// [`RoofPrior::fit`] with other settings of the trees.
    pub fn fit_with(records: &[&BuildingRecord], options: BoostOptions) -> Self {
        let mut records: Vec<&BuildingRecord> =
            records.iter().copied().filter(|r| !r.is_part).collect();
        records.sort_by_key(|r| r.id);
        records.dedup_by_key(|r| r.id);
        let frame = records
            .iter()
            .find_map(|r| r.outers.first()?.nodes.first())
            .map_or(LocalFrame::new(0.0, 0.0, 0.0), |n| {
                LocalFrame::new(n.lon, n.lat, 0.0)
            });
        let measured: Vec<(&BuildingRecord, Outline)> = records
            .iter()
            .filter_map(|r| Some((*r, Outline::of(r, &frame)?)))
            .collect();
        let outlines: Vec<Outline> = measured.iter().map(|(_, o)| *o).collect();
        let labels: Vec<Option<usize>> = measured
            .iter()
            .map(|(r, _)| tagged_class(r).map(RoofClass::index))
            .collect();
        let neighbourhood = Neighbourhood::new(&outlines);
        let row = |i: usize| {
            let (r, o) = &measured[i];
            let mut row = own_features(r, o);
            row.extend(neighbourhood.features(i, &labels));
            row
        };

        let mut tagged: Vec<usize> = (0..measured.len())
            .filter(|&i| labels[i].is_some())
            .collect();
        if tagged.len() > MAX_EXAMPLES {
            let hash =
                |i: &usize| xxhash_rust::xxh3::xxh3_64(measured[*i].0.id.to_string().as_bytes());
            tagged.sort_by_key(hash);
            tagged.truncate(MAX_EXAMPLES);
            tagged.sort_unstable();
        }
        let examples: Vec<Example> = tagged
            .iter()
            .map(|&i| Example {
                rows: vec![row(i)],
                label: labels[i].unwrap_or(0),
            })
            .collect();
        let mut per_class = [0usize; 3];
        for e in &examples {
            per_class[e.label] += 1;
        }
        let majority_share = if examples.is_empty() {
            0.0
        } else {
            *per_class.iter().max().unwrap_or(&0) as f64 / examples.len() as f64
        };
        let identity = identity(&examples, &options);
        let mut report = PriorReport {
            buildings: measured.len(),
            tagged: examples.len(),
            tagged_per_class: per_class,
            predicted: 0,
            cross_validated_accuracy: None,
            cross_validated_correct: None,
            confusion: None,
            majority_share,
            abstained: None,
            predictor: "none",
            identity,
        };
        let classes_present = per_class.iter().filter(|&&n| n > 0).count();
        if examples.len() < MIN_TAGGED || classes_present < 2 {
            report.abstained = Some(format!(
                "{} tagged buildings of {} roof classes: at least {MIN_TAGGED} of 2 classes are needed",
                examples.len(),
                classes_present
            ));
            // With one class only, its predictions are that class (reported, never applied).
            if examples.len() < MIN_TO_FIT {
                return Self {
                    report,
                    probabilities: HashMap::new(),
                };
            }
        }
        let fit = |train: &[&Example]| {
            let rows: Vec<&[f32]> = train.iter().map(|e| e.rows[0].as_slice()).collect();
            let labels: Vec<usize> = train.iter().map(|e| e.label).collect();
            BoostedTrees::fit(&rows, &labels, 3, options)
        };
        let predict = |m: &BoostedTrees, rows: &[Vec<f32>]| m.probabilities(rows.first()?);
        let cv = cross_validate_with(&examples, 3, FOLDS, fit, predict);
        let all: Vec<&Example> = examples.iter().collect();
        let model = fit(&all);
        let (Some(cv), Some(model)) = (cv, model) else {
            report.abstained = Some("the trees could not be fitted".to_owned());
            return Self {
                report,
                probabilities: HashMap::new(),
            };
        };
        // Trees that do not beat the most common class out of fold predict no better than the
        // class shares do: the shares are the prediction then.
        let margin = required_margin(majority_share, examples.len());
        let trees_help = cv.accuracy >= majority_share + margin;
        if report.abstained.is_none() && !trees_help {
            report.abstained = Some(format!(
                "cross-validated accuracy {:.1} % does not beat the most common class ({:.1} %) by {:.1} points",
                100.0 * cv.accuracy,
                100.0 * majority_share,
                100.0 * margin
            ));
        }
        report.cross_validated_accuracy = Some(cv.accuracy);
        report.cross_validated_correct = Some(cv.correct);
        report.confusion = Some(cv.confusion);
        let shares = per_class.map(|n| (n as f32 + 1.0) / (examples.len() as f32 + 3.0));
        report.predictor = if trees_help { "trees" } else { "class_shares" };
        let mut probabilities = HashMap::new();
        for (i, (r, _)) in measured.iter().enumerate() {
            if r.tags.contains_key("roof:shape") {
                continue;
            }
            if !trees_help {
                probabilities.insert(r.id, shares);
            } else if let Some(p) = model.probabilities(&row(i)) {
                probabilities.insert(r.id, [p[0], p[1], p[2]]);
            }
        }
        report.predicted = probabilities.len();
        Self {
            report,
            probabilities,
        }
    }

    /// Whether the prior's predictions are applied (it did not abstain).
    pub fn is_applied(&self) -> bool {
        self.report.abstained.is_none()
    }

    /// The class probabilities (flat, gabled, hipped) of an untagged building of the area.
    pub fn probabilities(&self, id: &OsmId) -> Option<[f32; 3]> {
        self.probabilities.get(id).copied()
    }

    /// The most probable class of an untagged building, and its probability.
    pub fn prediction(&self, id: &OsmId) -> Option<(RoofClass, f32)> {
        let p = self.probabilities(id)?;
        let c = argmax(&p);
        Some((RoofClass::ALL[c], p[c]))
    }

    /// Buildings given probabilities, in id order.
    pub fn predicted_ids(&self) -> Vec<OsmId> {
        let mut ids: Vec<OsmId> = self.probabilities.keys().copied().collect();
        ids.sort_unstable();
        ids
    }

    /// Bytes it occupies, generously counted (for caches): at most [`PREDICTION_BYTES`] per
    /// building it predicts, plus a fixed part.
    pub fn byte_size(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.probabilities.capacity() * (std::mem::size_of::<(OsmId, [f32; 3])>() + 8)
            + 512
    }
}

/// The most a prior weighs per building of its area (as [`RoofPrior::byte_size`] counts): one
/// entry of its table, with the table's spare capacity (at most as much again).
pub const PREDICTION_BYTES: usize = 2 * (std::mem::size_of::<(OsmId, [f32; 3])>() + 8);

/// The roof classifier's probabilities for a building together with the prior's: their
/// normalised product (Bayes' rule). The classifier learned from classes in equal shares, so its
/// probabilities stand for how well the image fits each class, and the prior's say how common
/// each class is for such a building in the area. `image` alone when the product vanishes.
pub fn combine(image: [f32; 3], prior: [f32; 3]) -> [f32; 3] {
    let product = [
        image[0] * prior[0],
        image[1] * prior[1],
        image[2] * prior[2],
    ];
    let sum: f32 = product.iter().sum();
    if sum.is_finite() && sum > 1e-12 {
        product.map(|p| p / sum)
    } else {
        image
    }
}

/// The digest of what a prior learned from and how.
fn identity(examples: &[Example], options: &BoostOptions) -> String {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    h.update(VERSION.as_bytes());
    h.update(format!("{options:?}").as_bytes());
    for e in examples {
        h.update(&(e.label as u32).to_le_bytes());
        for v in &e.rows[0] {
            h.update(&v.to_bits().to_le_bytes());
        }
    }
    format!("{:016x}", h.digest())
}

#[cfg(test)]
mod tests;

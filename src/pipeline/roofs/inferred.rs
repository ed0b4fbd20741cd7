//! `roofs=inferred`: each building without `roof:shape` takes the class the roof prior of its
//! area gives it (docs/extensions.md section 4) when the prior does not abstain and the
//! probability reaches [`APPLY_THRESHOLD`]; otherwise it keeps the default. The cache key holds
//! a digest of the priors' identities.

use super::{candidates, priors_of, scope_of};
use crate::cache::RoofSource;
use crate::error::AppError;
use crate::pipeline::Generator;
use crate::pipeline::PipelineError;
use crate::source::{AreaBuildings, PriorScope};
use citymesh_core::osm::OsmId;
use citymesh_core::roof_prior::{APPLY_THRESHOLD, PriorReport};
use citymesh_core::scene::{Chooser, RoofChoice, SceneArea};
use serde::Serialize;
use std::sync::Arc;
use utoipa::ToSchema;

/// An area's roofs with `roofs=inferred`.
pub struct InferredRoofs {
    pub buildings: AreaBuildings,
    pub choice: Arc<RoofChoice>,
    /// The cache key's roof part.
    pub source: RoofSource,
    pub figures: InferredFigures,
}

/// How an area's untagged buildings stand with `roofs=inferred`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, ToSchema)]
pub struct InferredFigures {
    /// Buildings without `roof:shape` whose shape the prior chose.
    pub inferred: usize,
    /// Buildings whose prediction is below the threshold (kept at the default).
    pub uncertain: usize,
    /// Buildings whose area's prior abstains or has no prediction for them (kept at the
    /// default).
    pub not_inferred: usize,
    /// The probability a prediction must reach to be applied.
    pub threshold: f32,
    /// The priors used, one per area whose tags taught them.
    pub priors: Vec<PriorFigures>,
}

/// One prior: where it learned and how well (out of fold on its tagged buildings).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct PriorFigures {
    /// `all` (the `--osm` files) or the data tile `z/x/y` whose buildings taught it.
    pub scope: String,
    /// Buildings of that area, tagged ones learned from (flat, gabled, hipped), untagged ones
    /// predicted.
    pub buildings: usize,
    pub tagged: usize,
    pub tagged_per_class: Vec<usize>,
    pub predicted: usize,
    /// Out-of-fold accuracy on the tagged buildings (5 folds), and what always answering their
    /// most common class would score.
    pub cross_validated_accuracy: Option<f64>,
    pub majority_share: f64,
    /// `confusion[truth][predicted]` out of fold (flat, gabled, hipped).
    pub confusion: Option<Vec<Vec<usize>>>,
    /// Why it is not applied, if it is not.
    pub abstained: Option<String>,
    /// `trees`, or `class_shares` when the trees do not beat the most common class (every
    /// prediction is then the tagged classes' shares), or `none` (too few to predict).
    pub predictor: String,
    /// Digest of its training rows, labels and settings.
    pub identity: String,
}

impl PriorFigures {
    pub fn of(scope: String, r: &PriorReport) -> Self {
        Self {
            scope,
            buildings: r.buildings,
            tagged: r.tagged,
            tagged_per_class: r.tagged_per_class.to_vec(),
            predicted: r.predicted,
            cross_validated_accuracy: r.cross_validated_accuracy,
            majority_share: r.majority_share,
            confusion: r.confusion.clone(),
            abstained: r.abstained.clone(),
            predictor: r.predictor.to_owned(),
            identity: r.identity.clone(),
        }
    }
}

/// The roofs of `area`'s buildings with `roofs=inferred`.
pub async fn inferred_roofs(
    generator: &Generator,
    area: SceneArea,
) -> Result<InferredRoofs, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| PipelineError::InvalidArea(e.to_string()))?;
    let buildings = generator.source.buildings(&bbox).await?;
    let set = buildings.set.clone();
    let worker = generator.clone();
    let wanted: Vec<(OsmId, Option<PriorScope>)> =
        crate::pipeline::run_blocking(generator, move || {
            Ok(candidates(&set, area)?
                .into_iter()
                .map(|r| (r.id, scope_of(&worker, r)))
                .collect())
        })
        .await?;
    let scopes: Vec<PriorScope> = wanted.iter().filter_map(|(_, s)| *s).collect();
    let priors = priors_of(generator, scopes).await?;
    let mut choice = RoofChoice::new();
    let mut figures = InferredFigures {
        threshold: APPLY_THRESHOLD,
        ..InferredFigures::default()
    };
    for (id, scope) in &wanted {
        let prior = scope
            .and_then(|s| priors.get(&s))
            .filter(|p| p.is_applied());
        match prior.and_then(|p| p.prediction(id)) {
            Some((class, p)) if p >= APPLY_THRESHOLD => {
                choice.insert_by(*id, class.shape(), p, Chooser::Prior);
                figures.inferred += 1;
            }
            Some(_) => figures.uncertain += 1,
            None => figures.not_inferred += 1,
        }
    }
    let mut used: Vec<_> = priors.iter().collect();
    used.sort_by_key(|(s, _)| s.name());
    let mut digest = xxhash_rust::xxh3::Xxh3::new();
    for (scope, prior) in &used {
        digest.update(scope.name().as_bytes());
        digest.update(prior.report.identity.as_bytes());
        figures
            .priors
            .push(PriorFigures::of(scope.name(), &prior.report));
    }
    Ok(InferredRoofs {
        buildings,
        choice: Arc::new(choice),
        source: RoofSource::Inferred {
            priors: digest.digest(),
        },
        figures,
    })
}

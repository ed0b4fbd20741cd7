//! `roofs=classified` (docs/extensions.md section 1): each building without a `roof:shape` (and
//! not part of a building with parts) takes the shape its prediction names when the prediction
//! is for its current footprint and clears the threshold. Where the roof prior of the
//! building's area applies (section 14), the prediction is the classifier's probabilities
//! combined with the prior's ([`combine`]). A tile never waits for classification: it is made
//! from the predictions there are, says how many of its buildings are still without one, and is
//! cached under a key holding a digest of the predictions and priors it used.

use super::{candidates, priors_of, scope_of};
use crate::cache::RoofSource;
use crate::error::AppError;
use crate::pipeline::Generator;
use crate::pipeline::PipelineError;
use crate::roofs::jobs::footprint_hash;
use crate::source::AreaBuildings;
use citymesh_core::osm::{BuildingRecord, OsmId};
use citymesh_core::roof_image::RoofClass;
use citymesh_core::roof_prior::combine;
use citymesh_core::scene::{RoofChoice, SceneArea};
use std::sync::Arc;

/// An area's roofs with `roofs=classified`.
pub struct ClassifiedRoofs {
    /// The area's buildings (loaded to find the candidates).
    pub buildings: AreaBuildings,
    pub choice: Arc<RoofChoice>,
    /// The cache key's roof part.
    pub source: RoofSource,
    pub figures: RoofFigures,
}

/// How an area's untagged buildings stand.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, utoipa::ToSchema)]
pub struct RoofFigures {
    /// Buildings without `roof:shape` whose shape comes from the classifier.
    pub classified: usize,
    /// Buildings with a prediction below the threshold (kept at the default).
    pub uncertain: usize,
    /// Buildings whose prediction combines the classifier's probabilities with the roof
    /// prior's of their area (counted in `classified` or `uncertain` too).
    pub with_prior: usize,
    /// Buildings without `roof:shape` and without a prediction yet (queued, failed, or never
    /// asked for: see `POST /classify`).
    pub pending: usize,
    /// What classifying the predictions used took (imagery, crop, inference), milliseconds.
    pub classification_ms: f64,
}

impl RoofFigures {
    /// The `X-Citymesh-Roofs` value: `classified, n` or `partial, n pending`.
    pub fn header(&self) -> String {
        if self.pending == 0 {
            format!("classified, {}", self.classified)
        } else {
            format!("partial, {} pending", self.pending)
        }
    }
}

/// The roofs of `area`'s buildings with `roofs=classified`.
pub async fn classified_roofs(
    generator: &Generator,
    area: SceneArea,
) -> Result<ClassifiedRoofs, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| PipelineError::InvalidArea(e.to_string()))?;
    let buildings = generator.source.buildings(&bbox).await?;
    let jobs = generator.roofs.active();
    let model_key = jobs.model_key();
    let set = buildings.set.clone();
    let worker = generator.clone();
    // Each candidate's id, footprint hash and prior scope.
    let wanted: Vec<(OsmId, String, Option<crate::source::PriorScope>)> =
        crate::pipeline::run_blocking(generator, move || {
            Ok(candidates(&set, area)?
                .into_iter()
                .map(|r| (r.id, outline_hash(r), scope_of(&worker, r)))
                .collect())
        })
        .await?;
    // Each candidate's prediction for its current footprint, if there is one: one pass over the
    // index, which workers keep writing to.
    let found: Vec<Option<([f32; 3], f64)>> = jobs.index.with(|index| {
        wanted
            .iter()
            .map(|(id, hash, _)| {
                index
                    .get(&id.to_string())
                    .filter(|p| &p.footprint_hash == hash)
                    .map(|p| (p.prediction.probabilities, p.work_ms))
            })
            .collect()
    });
    // Priors only for buildings with a prediction to combine with.
    let scopes = wanted
        .iter()
        .zip(&found)
        .filter(|(_, f)| f.is_some())
        .filter_map(|((_, _, s), _)| *s)
        .collect();
    let priors = priors_of(generator, scopes).await?;
    let mut choice = RoofChoice::new();
    let mut figures = RoofFigures::default();
    let mut digest = xxhash_rust::xxh3::Xxh3::new();
    for ((record_id, _, scope), found) in wanted.iter().zip(found) {
        let Some((mut probabilities, work_ms)) = found else {
            figures.pending += 1;
            continue;
        };
        figures.classification_ms += work_ms;
        digest.update(record_id.to_string().as_bytes());
        let prior = scope
            .and_then(|s| priors.get(&s))
            .filter(|p| p.is_applied())
            .and_then(|p| Some((p.probabilities(record_id)?, p.report.identity.as_str())));
        if let Some((from_prior, identity)) = prior {
            probabilities = combine(probabilities, from_prior);
            figures.with_prior += 1;
            digest.update(identity.as_bytes());
        }
        let p = crate::roofs::classifier::Prediction::new(probabilities);
        if p.confidence() >= jobs.threshold {
            let class: RoofClass = p.class();
            choice.insert(*record_id, class.shape(), p.confidence());
            figures.classified += 1;
            digest.update(class.name().as_bytes());
        } else {
            figures.uncertain += 1;
            digest.update(b"uncertain");
        }
    }
    Ok(ClassifiedRoofs {
        buildings,
        choice: Arc::new(choice),
        source: RoofSource::Classified {
            model: model_key,
            predictions: digest.digest(),
        },
        figures,
    })
}

/// The footprint hash of a record's outer ring, as jobs store it.
fn outline_hash(record: &BuildingRecord) -> String {
    let ring: Vec<[f64; 2]> = record
        .outers
        .first()
        .map(|o| o.nodes.iter().map(|n| [n.lon, n.lat]).collect())
        .unwrap_or_default();
    footprint_hash(&ring)
}

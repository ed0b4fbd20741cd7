//! Where an area's roof shapes come from (`roofs=osm|classified`, docs/method.md section 11).
//! With `classified`, each building without a `roof:shape` (and not part of a building with
//! parts) takes the shape its prediction names when the prediction is for its current footprint
//! and clears the threshold. A tile never waits for classification: it is made from the
//! predictions there are, says how many of its buildings are still without one, and is cached
//! under a key holding a digest of the predictions it used.

use crate::cache::RoofSource;
use crate::error::AppError;
use crate::jobs::footprint_hash;
use crate::source::AreaBuildings;
use crate::state::AppState;
use citymesh_core::osm::BuildingRecord;
use citymesh_core::roof_image::RoofClass;
use citymesh_core::scene::{RoofChoice, SceneArea};
use serde::Deserialize;
use std::sync::Arc;

/// Where roof shapes come from, as asked.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize, utoipa::ToSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum RoofsParam {
    /// `roof:shape` tags, else flat (the paper's default, without computer vision).
    #[default]
    Osm,
    /// Tags, and for untagged buildings the roof classifier's predictions.
    Classified,
}

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
    state: &AppState,
    area: SceneArea,
) -> Result<ClassifiedRoofs, AppError> {
    let bbox = area
        .bbox()
        .map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))?;
    let buildings = state.source.buildings(&bbox).await?;
    let jobs = state.roofs.active();
    let model_key = jobs.model_key();
    let set = buildings.set.clone();
    let (choice, figures, digest) = crate::pipeline::run_blocking(state, move || {
        let request = area
            .request(&set)
            .map_err(|e| AppError::bad_request("invalid_tile", e.to_string()))?;
        let mut choice = RoofChoice::new();
        let mut figures = RoofFigures::default();
        let mut digest = xxhash_rust::xxh3::Xxh3::new();
        jobs.index.with(|index| {
            for group in &request.groups {
                let records = set.cluster_records(group);
                if records.iter().any(|r| r.is_part) {
                    continue;
                }
                for record in records {
                    if record.tags.contains_key("roof:shape") {
                        continue;
                    }
                    let id = record.id.to_string();
                    let found = index
                        .get(&id)
                        .filter(|p| p.footprint_hash == outline_hash(record));
                    let Some(found) = found else {
                        figures.pending += 1;
                        continue;
                    };
                    let p = found.prediction;
                    figures.classification_ms += found.work_ms;
                    digest.update(id.as_bytes());
                    if p.confidence() >= jobs.threshold {
                        let class: RoofClass = p.class();
                        choice.insert(record.id, class.shape(), p.confidence());
                        figures.classified += 1;
                        digest.update(class.name().as_bytes());
                    } else {
                        figures.uncertain += 1;
                        digest.update(b"uncertain");
                    }
                }
            }
        });
        Ok((choice, figures, digest.digest()))
    })
    .await?;
    Ok(ClassifiedRoofs {
        buildings,
        choice: Arc::new(choice),
        source: RoofSource::Classified {
            model: model_key,
            predictions: digest,
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

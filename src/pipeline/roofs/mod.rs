//! Where an area's roof shapes come from (`roofs=osm|classified|inferred`): tags alone, the
//! roof classifier's predictions ([`classified`], docs/extensions.md section 1), or the roof prior
//! learned from the area's tags ([`inferred`], section 14). Both choose shapes only for
//! buildings without `roof:shape` that are not part of a building with parts ([`candidates`]),
//! and the tile cache keys hold a digest of what chose them.

mod classified;
mod inferred;

pub use classified::{ClassifiedRoofs, RoofFigures, classified_roofs};
pub use inferred::{InferredFigures, InferredRoofs, PriorFigures, inferred_roofs};

use crate::error::AppError;
use crate::pipeline::Generator;
use crate::pipeline::PipelineError;
use crate::source::PriorScope;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::osm::BuildingRecord;
use citymesh_core::roof_prior::RoofPrior;
use citymesh_core::scene::SceneArea;
use serde::Deserialize;
use std::collections::HashMap;
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
    /// Tags, and for untagged buildings the roof classifier's predictions (combined with the
    /// roof prior's where it applies).
    Classified,
    /// Tags, and for untagged buildings the roof prior learned from the tagged buildings of
    /// their area (no imagery).
    Inferred,
}

/// The buildings of `area` whose roof shape may be chosen: those without `roof:shape`, outside
/// groups with `building:part`s. Blocking.
pub fn candidates(set: &BuildingSet, area: SceneArea) -> Result<Vec<&BuildingRecord>, AppError> {
    let request = area
        .request(set)
        .map_err(|e| PipelineError::InvalidArea(e.to_string()))?;
    let mut out = Vec::new();
    for group in &request.groups {
        let records = set.cluster_records(group);
        if records.iter().any(|r| r.is_part) {
            continue;
        }
        out.extend(
            records
                .into_iter()
                .filter(|r| !r.tags.contains_key("roof:shape")),
        );
    }
    Ok(out)
}

/// The prior scope of a building: that of its outline's first node.
pub fn scope_of(generator: &Generator, record: &BuildingRecord) -> Option<PriorScope> {
    let n = record.outers.first()?.nodes.first()?;
    Some(generator.source.prior_scope(n.lon, n.lat))
}

/// The priors of `scopes`, held or fitted now (each on the blocking pool, in a generation slot).
pub async fn priors_of(
    generator: &Generator,
    scopes: Vec<PriorScope>,
) -> Result<HashMap<PriorScope, Arc<RoofPrior>>, AppError> {
    let mut out = HashMap::new();
    for scope in scopes {
        if out.contains_key(&scope) {
            continue;
        }
        let (prior, held) = generator
            .priors
            .get_or_fit(scope, async {
                let records = generator.source.prior_records(scope).await?;
                crate::pipeline::run_blocking(generator, move || {
                    let refs: Vec<&BuildingRecord> = records.iter().map(AsRef::as_ref).collect();
                    let prior = RoofPrior::fit(&refs);
                    tracing::info!(
                        scope = %scope.name(),
                        identity = %prior.report.identity,
                        tagged = prior.report.tagged,
                        accuracy = ?prior.report.cross_validated_accuracy,
                        abstained = ?prior.report.abstained,
                        "roof prior fitted"
                    );
                    Ok(Arc::new(prior))
                })
                .await
            })
            .await?;
        generator.metrics.cache("roof_prior", held);
        out.insert(scope, prior);
    }
    Ok(out)
}

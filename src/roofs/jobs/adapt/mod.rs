//! Adapting the roof classifier to the served imagery from OpenStreetMap's own tags
//! (docs/extensions.md section 3): the buildings of a box that carry a `roof:shape` of the three
//! classes are cropped from the imagery as any building is, the model embeds them, and a head is
//! fitted, cross-validated and stored in the server's database (`roof_adaptations`, SQLite or
//! PostgreSQL); when fitted, it is put in use for this imagery. Progress is kept in the database
//! as it goes, so a client can follow it and nothing reports "running" after a restart.

mod run;
mod store;

pub use run::{AdaptFailure, AdaptPolicy, AdaptationRun, Progress, fit_on_imagery, run_adaptation};
pub use store::AdaptationStore;

use super::job::NewJob;
use super::select::{Selection, held_by, select_buildings};
use citymesh_core::building::roof::RoofShape;
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::BuildingRecord;
use citymesh_core::roof_image::RoofClass;
use serde::Serialize;
use utoipa::ToSchema;

/// Most tagged buildings of one class used as examples (the first in the data's order): bounds
/// the imagery fetched and the memory held (a crop is 37 KB).
pub const MAX_EXAMPLES_PER_CLASS: usize = 300;

/// Who runs an adaptation, and how long it holds it without extending (a process that dies
/// leaves it to run out).
#[derive(Debug, Clone)]
pub struct Lease {
    /// The process (replica) running it.
    pub owner: String,
    pub duration: std::time::Duration,
}

impl Lease {
    /// When a lease taken at `now` (ms) ends.
    pub(super) fn end(&self, now: i64) -> i64 {
        now.saturating_add(i64::try_from(self.duration.as_millis()).unwrap_or(i64::MAX))
    }
}

/// An adaptation as a client sees it.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct AdaptationStatus {
    pub id: String,
    /// `running`; `done` (a head was fitted and is in use); `not_better` (a head was fitted but
    /// its cross-validated accuracy does not beat the shipped head's: not used); `too_few`
    /// (fewer than 20 examples of a class could be cropped: the shipped head stays); `failed`;
    /// `cancelled` (stopped by `DELETE`); `withdrawn` (its head taken out of use by `DELETE`).
    pub state: String,
    pub bbox: String,
    pub imagery_id: String,
    /// The model whose embedding the head reads.
    pub model_id: String,
    /// Tagged buildings used as examples, by class.
    pub examples: ClassCounts,
    /// Examples cropped so far, and those whose imagery failed.
    pub cropped: u64,
    pub crop_failed: u64,
    /// Share of the examples cropped, percent (100 once fitted).
    pub percent: f64,
    /// The fitted head's id (predictions made with it record `MODEL+head-ID`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub head_id: Option<String>,
    /// The cross-validated report on the examples: accuracy, confusion matrix, the shipped
    /// head's accuracy on them and the threshold chosen.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub report: Option<serde_json::Value>,
    /// Why it failed or stopped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Counts by class.
#[derive(Debug, Clone, Copy, Default, Serialize, ToSchema)]
pub struct ClassCounts {
    pub flat: u64,
    pub gabled: u64,
    pub hipped: u64,
}

impl ClassCounts {
    pub fn of(counts: [usize; 3]) -> Self {
        Self {
            flat: counts[0] as u64,
            gabled: counts[1] as u64,
            hipped: counts[2] as u64,
        }
    }

    pub(super) fn total(&self) -> u64 {
        self.flat + self.gabled + self.hipped
    }
}

/// A tagged building to learn from.
pub struct AdaptExample {
    pub job: NewJob,
    pub class: RoofClass,
}

/// The tagged buildings of `records` that `bbox` holds (the core's rule; all without a box), with
/// their class, at most [`MAX_EXAMPLES_PER_CLASS`] per class.
pub fn tagged_examples<R: std::borrow::Borrow<BuildingRecord>>(
    records: &[R],
    bbox: Option<&GeoBbox>,
) -> Vec<AdaptExample> {
    let class_of: std::collections::HashMap<String, RoofClass> = records
        .iter()
        .map(R::borrow)
        .filter_map(|r| {
            let shape = RoofShape::from_tag(r.tags.get("roof:shape")?)?;
            Some((r.id.to_string(), RoofClass::of_shape(shape)?))
        })
        .collect();
    let (jobs, _) = select_buildings(&held_by(records, bbox), Selection::All);
    let mut taken = [0usize; 3];
    let mut out = Vec::new();
    for job in jobs {
        let Some(&class) = class_of.get(&job.osm_id) else {
            continue;
        };
        if taken[class.index()] >= MAX_EXAMPLES_PER_CLASS {
            continue;
        }
        taken[class.index()] += 1;
        out.push(AdaptExample { job, class });
    }
    out
}

/// How many examples each class has (flat, gabled, hipped).
pub fn class_counts(examples: &[AdaptExample]) -> [usize; 3] {
    let mut counts = [0usize; 3];
    examples.iter().for_each(|e| counts[e.class.index()] += 1);
    counts
}

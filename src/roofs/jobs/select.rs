//! Which buildings of an area get a roof job (paper 2.2): buildings, not parts, without parts of
//! their own, and (unless asked for every one) without a `roof:shape`.

use super::job::NewJob;
use citymesh_core::building::cluster::part_of;
use citymesh_core::building::in_box::{MIN_FOOTPRINT_M2, footprint_area_m2, holds};
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::BuildingRecord;
use std::borrow::Borrow;
use std::collections::{BTreeMap, HashSet};

/// Which buildings to classify.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    /// Only those without `roof:shape` (the paper's rule).
    Untagged,
    /// Every building without parts, tagged or not (to measure agreement with the tags).
    All,
}

/// The jobs, and the buildings left out by reason (`part`, `tagged`, `has_parts`).
pub fn select_buildings<R: Borrow<BuildingRecord>>(
    records: &[R],
    selection: Selection,
) -> (Vec<NewJob>, BTreeMap<String, u64>) {
    let mut skipped: BTreeMap<String, u64> = BTreeMap::new();
    let mut jobs = Vec::new();
    let parts: Vec<&BuildingRecord> = records
        .iter()
        .map(R::borrow)
        .filter(|r| r.is_part)
        .collect();
    for record in records.iter().map(R::borrow) {
        let reason = if record.is_part {
            Some("part")
        } else if selection == Selection::Untagged && record.tags.contains_key("roof:shape") {
            Some("tagged")
        } else if parts.iter().any(|p| part_of(p, record)) {
            Some("has_parts")
        } else {
            None
        };
        if let Some(reason) = reason {
            *skipped.entry(reason.to_owned()).or_default() += 1;
            continue;
        }
        let Some(outer) = record.outers.first() else {
            continue;
        };
        jobs.push(NewJob {
            osm_id: record.id.to_string(),
            footprint: outer.nodes.iter().map(|n| [n.lon, n.lat]).collect(),
        });
    }
    (jobs, skipped)
}

/// The buildings of `records` that `bbox` holds (the core's rule, [`holds`]); all without a box.
pub fn held_by<'a, R: Borrow<BuildingRecord>>(
    records: &'a [R],
    bbox: Option<&GeoBbox>,
) -> Vec<&'a BuildingRecord> {
    records
        .iter()
        .map(R::borrow)
        .filter(|r| bbox.is_none_or(|b| holds(b, r)))
        .collect()
}

/// The jobs for the buildings `bbox` holds (the core's rule, [`holds`]; every building when
/// there is no box), only those named in `wanted` when it is given, and the buildings left out
/// by reason: those of [`select_buildings`] among the box's buildings, and `too_small` for
/// footprints under [`MIN_FOOTPRINT_M2`]. What `POST /classify` and `citymesh classify` queue.
pub fn jobs_in_box<R: Borrow<BuildingRecord>>(
    records: &[R],
    bbox: Option<&GeoBbox>,
    selection: Selection,
    wanted: Option<&HashSet<&str>>,
) -> (Vec<NewJob>, BTreeMap<String, u64>) {
    let (candidates, mut skipped) = select_buildings(&held_by(records, bbox), selection);
    let mut jobs = Vec::with_capacity(candidates.len());
    for job in candidates {
        if wanted.is_some_and(|w| !w.contains(job.osm_id.as_str())) {
            continue;
        }
        if footprint_area_m2(&job.footprint) < MIN_FOOTPRINT_M2 {
            *skipped.entry("too_small".to_owned()).or_default() += 1;
            continue;
        }
        jobs.push(job);
    }
    skipped.retain(|_, n| *n > 0);
    (jobs, skipped)
}

//! Which buildings of an area get a roof job (paper 2.2): buildings, not parts, without parts of
//! their own, and (unless asked for every one) without a `roof:shape`.

use super::queue::NewJob;
use citymesh_core::building::cluster::part_of;
use citymesh_core::osm::BuildingRecord;
use std::borrow::Borrow;
use std::collections::BTreeMap;

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

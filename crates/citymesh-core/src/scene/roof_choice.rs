//! Roof shapes chosen outside the data: for buildings whose OSM data has no `roof:shape`, a shape
//! decided elsewhere (classified from imagery, docs/extensions.md section 1, or inferred from the
//! area's tags, section 14) stands in for the tag. A tag always wins: a chosen shape never
//! replaces one the data names.

use crate::building::feature::{CHOSEN_ROOF_ORIGIN, CHOSEN_ROOF_PROBABILITY, INFERRED};
use crate::building::roof::RoofShape;
use crate::osm::{BuildingRecord, OsmId};
use std::borrow::Cow;
use std::collections::HashMap;

/// Who chose a shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chooser {
    /// The roof classifier, from imagery (with the prior, where one applies).
    Classifier,
    /// The roof prior learned from the area's tags alone.
    Prior,
}

/// Shapes for records without a `roof:shape` tag, by OSM id, each with the probability its
/// chooser gave it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RoofChoice {
    by_id: HashMap<OsmId, (RoofShape, f32, Chooser)>,
}

impl RoofChoice {
    pub fn new() -> Self {
        Self::default()
    }

    /// A shape the classifier chose.
    pub fn insert(&mut self, id: OsmId, shape: RoofShape, probability: f32) {
        self.by_id
            .insert(id, (shape, probability, Chooser::Classifier));
    }

    /// A shape chosen by `chooser`.
    pub fn insert_by(&mut self, id: OsmId, shape: RoofShape, probability: f32, chooser: Chooser) {
        self.by_id.insert(id, (shape, probability, chooser));
    }

    pub fn get(&self, id: &OsmId) -> Option<RoofShape> {
        self.by_id.get(id).map(|&(shape, _, _)| shape)
    }

    pub fn len(&self) -> usize {
        self.by_id.len()
    }

    pub fn is_empty(&self) -> bool {
        self.by_id.is_empty()
    }

    /// The record as the generator should see it: with the chosen shape as its `roof:shape` when
    /// it has none and one was chosen (a copy, marked with the probability under
    /// [`CHOSEN_ROOF_PROBABILITY`]), else itself.
    pub fn apply<'a>(&self, record: Cow<'a, BuildingRecord>) -> Cow<'a, BuildingRecord> {
        match self.by_id.get(&record.id) {
            Some(&(shape, probability, chooser)) if !record.tags.contains_key("roof:shape") => {
                let mut patched = record.into_owned();
                patched
                    .tags
                    .insert("roof:shape".to_owned(), shape.tag().to_owned());
                patched.tags.insert(
                    CHOSEN_ROOF_PROBABILITY.to_owned(),
                    format!("{probability:.4}"),
                );
                if chooser == Chooser::Prior {
                    patched
                        .tags
                        .insert(CHOSEN_ROOF_ORIGIN.to_owned(), INFERRED.to_owned());
                }
                Cow::Owned(patched)
            }
            _ => record,
        }
    }

    /// `record` without a [`CHOSEN_ROOF_PROBABILITY`] or [`CHOSEN_ROOF_ORIGIN`] tag of its own
    /// (data cannot pose as a prediction): itself, or a copy without them.
    pub fn unmarked(record: &BuildingRecord) -> Cow<'_, BuildingRecord> {
        if record.tags.contains_key(CHOSEN_ROOF_PROBABILITY)
            || record.tags.contains_key(CHOSEN_ROOF_ORIGIN)
        {
            let mut clean = record.clone();
            clean.tags.remove(CHOSEN_ROOF_PROBABILITY);
            clean.tags.remove(CHOSEN_ROOF_ORIGIN);
            Cow::Owned(clean)
        } else {
            Cow::Borrowed(record)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::Tags;

    fn record(id: i64, shape: Option<&str>) -> BuildingRecord {
        let mut tags = Tags::new();
        tags.insert("building".into(), "yes".into());
        if let Some(s) = shape {
            tags.insert("roof:shape".into(), s.into());
        }
        BuildingRecord {
            id: OsmId::Way(id),
            is_part: false,
            outers: Vec::new(),
            inners: Vec::new(),
            tags,
        }
    }

    #[test]
    fn a_shape_the_prior_chose_is_marked_inferred_and_data_cannot_pose_as_one() {
        let mut choice = RoofChoice::new();
        choice.insert_by(OsmId::Way(1), RoofShape::Gabled, 0.8, Chooser::Prior);
        let applied = choice.apply(Cow::Owned(record(1, None)));
        assert_eq!(
            applied.tags.get(CHOSEN_ROOF_ORIGIN).map(String::as_str),
            Some(INFERRED)
        );
        assert_eq!(
            applied
                .tags
                .get(CHOSEN_ROOF_PROBABILITY)
                .map(String::as_str),
            Some("0.8000")
        );
        let mut forged = record(2, Some("gabled"));
        forged
            .tags
            .insert(CHOSEN_ROOF_ORIGIN.into(), INFERRED.into());
        let clean = RoofChoice::unmarked(&forged);
        assert!(!clean.tags.contains_key(CHOSEN_ROOF_ORIGIN));
    }

    #[test]
    fn a_chosen_shape_fills_a_missing_tag_and_never_replaces_one() {
        let mut choice = RoofChoice::new();
        choice.insert(OsmId::Way(1), RoofShape::Hipped, 0.9);
        choice.insert(OsmId::Way(2), RoofShape::Hipped, 0.9);
        let untagged = record(1, None);
        let tagged = record(2, Some("gabled"));
        let other = record(3, None);
        assert_eq!(
            choice
                .apply(Cow::Borrowed(&untagged))
                .tags
                .get("roof:shape")
                .map(String::as_str),
            Some("hipped")
        );
        assert!(matches!(
            choice.apply(Cow::Borrowed(&tagged)),
            Cow::Borrowed(_)
        ));
        assert_eq!(
            choice
                .apply(Cow::Borrowed(&tagged))
                .tags
                .get("roof:shape")
                .map(String::as_str),
            Some("gabled")
        );
        assert!(matches!(
            choice.apply(Cow::Borrowed(&other)),
            Cow::Borrowed(_)
        ));
        assert_eq!(choice.len(), 2);
    }
}

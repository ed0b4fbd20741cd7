//! What went into the buildings of a scene: the statistics of the paper's Tables 2 and 3 (share of
//! flat roofs, roof shapes from tags or defaults) plus what was skipped and why.

use super::feature::BuildingFeature;
use super::params::{BuildingParams, HeightSource, ShapeSource};
use super::roof::RoofShape;
use crate::osm::{OsmId, Repaired, Skipped};
use serde::Serialize;
use std::collections::BTreeMap;

/// Building figures of one scene.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct BuildingStats {
    /// Records (buildings and parts) that produced a volume.
    pub generated: usize,
    /// Of those, `building:part`s.
    pub parts: usize,
    /// Records that could not be built, by reason.
    pub skipped: BTreeMap<&'static str, usize>,
    /// The skipped records themselves (OSM ids, e.g. `way/123`) with their reason.
    pub skipped_ids: Vec<(String, &'static str)>,
    /// Generated roofs by shape (OSM `roof:shape` names).
    pub roof_shapes: BTreeMap<&'static str, usize>,
    /// Roof shapes named by a `roof:shape` tag citymesh draws.
    pub shape_from_tag: usize,
    /// Roofs without `roof:shape`, given the default (flat).
    pub shape_default: usize,
    /// `roof:shape` values citymesh does not draw, rendered flat.
    pub shape_unsupported: usize,
    /// Total heights from `height`, from levels, and from the type default.
    pub height_from_tag: usize,
    pub height_from_levels: usize,
    pub height_default: usize,
    /// Tag values that were present but unusable (the fallback was used).
    pub invalid_tags: usize,
    /// Outlines entirely covered by their parts (only the parts are generated).
    pub outlines_covered_by_parts: usize,
    /// Edges between touching volumes whose hidden walls were removed.
    pub shared_walls: usize,
    /// Roof dividing segments dropped because they crossed another (the roof is still closed).
    pub dropped_constraints: usize,
    /// Generated records built with less than the data describes (e.g. `missing_inner_ring`),
    /// by OSM id.
    pub repaired_ids: Vec<(String, &'static str)>,
    /// The records whose `roof:shape` names no shape citymesh draws, with that value (drawn
    /// flat).
    pub unsupported_shape_ids: Vec<(String, String)>,
    /// Generated records whose drawn floor area differs from the area their outline leaves (less
    /// its courtyards, its parts and what the scene border cuts off) by more than
    /// [`MAX_AREA_LOSS_M2`], with the square metres lost (negative: drawn over).
    pub area_lost_ids: Vec<(String, f64)>,
    /// The generated records as clients see them, in generation order (a triangle's feature id
    /// is its index here).
    #[serde(skip)]
    pub features: Vec<BuildingFeature>,
}

/// A drawn floor may differ this much from its outline (m²) before it is reported.
pub const MAX_AREA_LOSS_M2: f64 = 0.5;

impl BuildingStats {
    /// Notes what reading the data found about the records a scene used (`used`): those that
    /// could not be read into a building at all are skipped, those read with less than the data
    /// describes are repaired. The server and `citymesh scene` report the same.
    pub fn note_reading(
        &mut self,
        skipped: &[Skipped],
        repaired: &[Repaired],
        used: &dyn Fn(OsmId) -> bool,
    ) {
        for s in skipped {
            self.skip(s.id, s.reason.name());
        }
        let used: Vec<&Repaired> = repaired.iter().filter(|r| used(r.id)).collect();
        if used.is_empty() {
            return;
        }
        self.repaired_ids
            .extend(used.iter().map(|r| (r.id.to_string(), r.what)));
        // And in the quality record of each building drawn from the record.
        let mut rows: std::collections::HashMap<OsmId, Vec<usize>> =
            std::collections::HashMap::new();
        for (row, f) in self.features.iter().enumerate() {
            rows.entry(f.id).or_default().push(row);
        }
        for r in used {
            for &row in rows.get(&r.id).into_iter().flatten() {
                let repairs = &mut self.features[row].quality.repairs;
                if !repairs.contains(&r.what) {
                    repairs.push(r.what);
                }
            }
        }
    }

    pub fn skip(&mut self, id: OsmId, reason: &'static str) {
        *self.skipped.entry(reason).or_default() += 1;
        self.skipped_ids.push((id.to_string(), reason));
    }

    /// Counts the parameters of one generated record.
    pub fn count(&mut self, is_part: bool, p: &BuildingParams) {
        if is_part {
            self.parts += 1;
        }
        *self.roof_shapes.entry(p.shape.tag()).or_default() += 1;
        match p.shape_source {
            ShapeSource::Tag => self.shape_from_tag += 1,
            ShapeSource::Default => self.shape_default += 1,
            ShapeSource::Unsupported => self.shape_unsupported += 1,
        }
        match p.height_source {
            HeightSource::Tag => self.height_from_tag += 1,
            HeightSource::Levels => self.height_from_levels += 1,
            HeightSource::TypeDefault => self.height_default += 1,
        }
    }

    /// Adds the figures of `other`, counted after these (lists keep their order).
    pub fn absorb(&mut self, other: BuildingStats) {
        // Every field named, so a new one cannot be forgotten here.
        let BuildingStats {
            generated,
            parts,
            skipped,
            skipped_ids,
            roof_shapes,
            shape_from_tag,
            shape_default,
            shape_unsupported,
            height_from_tag,
            height_from_levels,
            height_default,
            invalid_tags,
            outlines_covered_by_parts,
            shared_walls,
            dropped_constraints,
            repaired_ids,
            unsupported_shape_ids,
            area_lost_ids,
            features,
        } = other;
        self.generated += generated;
        self.parts += parts;
        for (k, v) in skipped {
            *self.skipped.entry(k).or_default() += v;
        }
        self.skipped_ids.extend(skipped_ids);
        for (k, v) in roof_shapes {
            *self.roof_shapes.entry(k).or_default() += v;
        }
        self.shape_from_tag += shape_from_tag;
        self.shape_default += shape_default;
        self.shape_unsupported += shape_unsupported;
        self.height_from_tag += height_from_tag;
        self.height_from_levels += height_from_levels;
        self.height_default += height_default;
        self.invalid_tags += invalid_tags;
        self.outlines_covered_by_parts += outlines_covered_by_parts;
        self.shared_walls += shared_walls;
        self.dropped_constraints += dropped_constraints;
        self.repaired_ids.extend(repaired_ids);
        self.unsupported_shape_ids.extend(unsupported_shape_ids);
        self.area_lost_ids.extend(area_lost_ids);
        self.features.extend(features);
    }

    /// The OSM ids (`way/123`) of the generated records, in generation order.
    pub fn generated_ids(&self) -> Vec<String> {
        self.features.iter().map(|f| f.id.to_string()).collect()
    }

    /// Roofs counted, of any shape.
    pub fn roofs(&self) -> usize {
        self.roof_shapes.values().sum()
    }

    /// Share of flat roofs in percent (paper Tables 2 and 3).
    pub fn flat_roof_percent(&self) -> f64 {
        percent(
            self.roof_shapes
                .get(RoofShape::Flat.tag())
                .copied()
                .unwrap_or(0),
            self.roofs(),
        )
    }

    /// Share of roof shapes that came from tags, in percent.
    pub fn shape_from_tag_percent(&self) -> f64 {
        percent(self.shape_from_tag, self.roofs())
    }

    /// Records skipped, for any reason.
    pub fn total_skipped(&self) -> usize {
        self.skipped.values().sum()
    }
}

fn percent(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        0.0
    } else {
        100.0 * part as f64 / whole as f64
    }
}

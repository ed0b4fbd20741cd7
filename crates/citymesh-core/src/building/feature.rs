//! What a client learns about one generated building when it picks it: the row of the GLB's
//! property table (`EXT_structural_metadata`) that the building's triangles point at through
//! their feature ids (`EXT_mesh_features`).

use super::cluster::record_bounds;
use super::in_box::bounds_centre;
use super::params::{BuildingParams, ShapeSource};
use super::tags::BuildingTags;
use crate::mesh::Rgb;
use crate::mesh::gltf::{ClassDef, Column, PropertyDef, PropertyTable, PropertyType};
use crate::osm::{BuildingRecord, OsmId, Tags};

/// The tag a shape chosen outside the data (the roof classifier) carries on the copy of the
/// record the generator sees, with the prediction's probability as its value. Only
/// [`crate::scene::RoofChoice`] sets it; a value in the data itself is dropped, so it cannot
/// pose as a prediction.
pub const CHOSEN_ROOF_PROBABILITY: &str = "citymesh:roof_probability";
/// Beside [`CHOSEN_ROOF_PROBABILITY`]: who chose the shape, when not the classifier.
pub const CHOSEN_ROOF_ORIGIN: &str = "citymesh:roof_origin";
/// The [`CHOSEN_ROOF_ORIGIN`] value of a shape the roof prior inferred from the area's tags.
pub const INFERRED: &str = "inferred";

/// Where a building's roof shape came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RoofOrigin {
    /// `roof:shape` names one of the shapes citymesh builds.
    Tag,
    /// The roof classifier, with the probability of its answer.
    Classifier { probability: f32 },
    /// The roof prior learned from the area's tags, with the probability of its answer.
    Inferred { probability: f32 },
    /// No usable `roof:shape` (none, or one citymesh does not draw): the default, flat.
    Default,
}

impl RoofOrigin {
    /// The name in the property table.
    pub fn name(self) -> &'static str {
        match self {
            RoofOrigin::Tag => "tag",
            RoofOrigin::Classifier { .. } => "classifier",
            RoofOrigin::Inferred { .. } => "inferred",
            RoofOrigin::Default => "default",
        }
    }
}

/// Which properties a building carries besides the named ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum TagProperties {
    /// The named properties of [`BUILDING_CLASS`] only.
    #[default]
    Named,
    /// Also every OSM tag of the element, as one JSON object (`osm_tags`).
    All,
}

/// One generated building (or `building:part`) as a client sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingFeature {
    pub id: OsmId,
    /// The value of `building` (or `building:part`), e.g. `house`, `yes`.
    pub building: String,
    pub name: Option<String>,
    /// Street and house number, postcode and city, as far as tagged.
    pub address: Option<String>,
    /// Total height above the ground, metres.
    pub height: f64,
    /// Height of the lowest floor above the ground, metres.
    pub min_height: f64,
    /// `building:levels`, when tagged.
    pub levels: Option<f64>,
    /// The roof shape built (an OSM `roof:shape` value).
    pub roof_shape: &'static str,
    pub roof_origin: RoofOrigin,
    pub wall_colour: Rgb,
    pub roof_colour: Rgb,
    /// The centre of the footprint's bounding box, degrees (`[lon, lat]`): the point the
    /// buildings a box holds are decided by.
    pub centre: [f64; 2],
    /// Every OSM tag of the element as a JSON object, when asked ([`TagProperties::All`]).
    pub osm_tags: Option<String>,
    /// How well its geometry was drawn.
    pub quality: Quality,
}

/// A building's geometry record, as 3DBAG ships validation codes: whether its group is a closed
/// surface and a strict 2-manifold, what was repaired, and its floor area drawn against the area
/// its outline leaves.
#[derive(Debug, Clone, PartialEq)]
pub struct Quality {
    /// Every edge of the building's group (the volumes it touches) is met by one running the
    /// other way.
    pub closed: bool,
    /// Every edge of the group has exactly two triangles.
    pub strict_manifold: bool,
    /// What was drawn other than the data describes (`overlap_cut_out`, ...), in order.
    pub repairs: Vec<&'static str>,
    /// Floor area drawn, m² (to 0.01).
    pub floor_area: f64,
    /// The area the outline leaves, m²: less its courtyards, its parts, smaller buildings drawn
    /// over it and what the scene border cuts off.
    pub outline_area: f64,
}

impl Default for Quality {
    fn default() -> Self {
        Self {
            closed: true,
            strict_manifold: true,
            repairs: Vec::new(),
            floor_area: 0.0,
            outline_area: 0.0,
        }
    }
}

impl BuildingFeature {
    /// The feature of `record`, built with `params` from `tags`.
    pub fn new(record: &BuildingRecord, tags: &BuildingTags, params: &BuildingParams) -> Self {
        let kind = if record.is_part {
            "building:part"
        } else {
            "building"
        };
        let roof_origin = match params.shape_source {
            ShapeSource::Tag => match chosen_probability(&record.tags) {
                Some(probability)
                    if record.tags.get(CHOSEN_ROOF_ORIGIN).map(String::as_str)
                        == Some(INFERRED) =>
                {
                    RoofOrigin::Inferred { probability }
                }
                Some(probability) => RoofOrigin::Classifier { probability },
                None => RoofOrigin::Tag,
            },
            ShapeSource::Default | ShapeSource::Unsupported => RoofOrigin::Default,
        };
        Self {
            id: record.id,
            building: record.tags.get(kind).cloned().unwrap_or_default(),
            name: record.tags.get("name").cloned(),
            address: address(&record.tags),
            height: params.height,
            min_height: params.min_height,
            levels: tags.levels,
            roof_shape: params.shape.tag(),
            roof_origin,
            wall_colour: params.wall_colour,
            roof_colour: params.roof_colour,
            centre: {
                let (lon, lat) = bounds_centre(record_bounds(record));
                [lon, lat]
            },
            osm_tags: None,
            quality: Quality::default(),
        }
    }

    /// The same feature carrying every OSM tag of `tags` (the record's, as in the data: what
    /// citymesh itself notes on a record, `citymesh:*`, is left out).
    pub fn with_every_tag(self, tags: &Tags) -> Self {
        let object: serde_json::Map<String, serde_json::Value> = tags
            .iter()
            .filter(|(k, _)| !k.starts_with("citymesh:"))
            .map(|(k, v)| (k.clone(), serde_json::Value::String(v.clone())))
            .collect();
        Self {
            osm_tags: Some(serde_json::Value::Object(object).to_string()),
            ..self
        }
    }
}

/// A property of the building class.
const fn property(
    name: &'static str,
    kind: PropertyType,
    description: &'static str,
) -> PropertyDef {
    PropertyDef {
        name,
        kind,
        description,
        semantic: None,
    }
}

/// A property CesiumJS styles also read by `semantic` (a name that is no identifier, like
/// `cesium#estimatedHeight`).
const fn styled(
    name: &'static str,
    semantic: &'static str,
    kind: PropertyType,
    description: &'static str,
) -> PropertyDef {
    PropertyDef {
        semantic: Some(semantic),
        ..property(name, kind, description)
    }
}

/// "None" for the optional numbers.
const NONE: Option<i32> = Some(-1);

/// The class of every row: what the property table (and the tileset's schema) holds per
/// building.
pub static BUILDING_CLASS: ClassDef = ClassDef {
    id: "building",
    description: "An OpenStreetMap building or building:part as citymesh generated it",
    properties: &[
        property(
            "osm_type",
            PropertyType::String,
            "OSM element type: way or relation",
        ),
        property("osm_id", PropertyType::Int64, "OSM element id"),
        property(
            "building",
            PropertyType::String,
            "Value of the building (or building:part) tag",
        ),
        property("name", PropertyType::String, "The name tag"),
        property(
            "address",
            PropertyType::String,
            "addr:street addr:housenumber, addr:postcode addr:city, as tagged",
        ),
        property(
            "height",
            PropertyType::Float32 { no_data: None },
            "Total height above the ground, metres (tag, levels or default)",
        ),
        property(
            "min_height",
            PropertyType::Float32 { no_data: None },
            "Height of the lowest floor above the ground, metres",
        ),
        property(
            "levels",
            PropertyType::Float32 { no_data: NONE },
            "building:levels, when tagged (-1: not tagged)",
        ),
        property(
            "roof_shape",
            PropertyType::String,
            "The roof shape built (an OSM roof:shape value)",
        ),
        property(
            "roof_source",
            PropertyType::String,
            "Where the roof shape came from: tag, classifier, inferred (the prior learned from the area's tags) or default",
        ),
        property(
            "roof_probability",
            PropertyType::Float32 { no_data: NONE },
            "The probability the classifier or the prior gave its shape (-1: from a tag or the default)",
        ),
        property(
            "wall_colour",
            PropertyType::String,
            "Wall colour, #rrggbb (sRGB)",
        ),
        property(
            "roof_colour",
            PropertyType::String,
            "Roof colour, #rrggbb (sRGB)",
        ),
        // The names Cesium OSM Buildings carries, so its styles and pick handlers work as they
        // are.
        property(
            "elementId",
            PropertyType::Int64,
            "OSM element id (as Cesium OSM Buildings names it)",
        ),
        property(
            "elementType",
            PropertyType::String,
            "OSM element type: way or relation (as Cesium OSM Buildings names it)",
        ),
        styled(
            "cesium_estimatedHeight",
            "cesium#estimatedHeight",
            PropertyType::Float32 { no_data: None },
            "Total height above the ground, metres (styles read it as cesium#estimatedHeight)",
        ),
        styled(
            "cesium_latitude",
            "cesium#latitude",
            PropertyType::Float64,
            "Latitude of the footprint's centre, degrees (styles read it as cesium#latitude)",
        ),
        styled(
            "cesium_longitude",
            "cesium#longitude",
            PropertyType::Float64,
            "Longitude of the footprint's centre, degrees (styles read it as cesium#longitude)",
        ),
        property(
            "osm_tags",
            PropertyType::String,
            "Every OSM tag of the element as a JSON object, when asked for (tags=all)",
        ),
        property(
            "closed",
            PropertyType::Boolean,
            "Whether the building's group (the volumes it touches) is a closed surface: every edge is met by one running the other way",
        ),
        property(
            "strict_manifold",
            PropertyType::Boolean,
            "Whether every edge of the building's group has exactly two triangles (false where volumes touch only along a corner line)",
        ),
        property(
            "repairs",
            PropertyType::String,
            "What was drawn other than the data describes, comma-separated (e.g. overlap_cut_out, courtyard_touches_a_ring, split_where_rings_touch); empty: nothing",
        ),
        property(
            "floor_area",
            PropertyType::Float32 { no_data: None },
            "Floor area drawn, square metres",
        ),
        property(
            "outline_area",
            PropertyType::Float32 { no_data: None },
            "The area the outline leaves (less its courtyards, its parts, smaller buildings drawn over it and the scene border), square metres",
        ),
    ],
};

/// The property table of `features`, a row each, in [`BUILDING_CLASS`]'s column order.
pub fn property_table(features: &[BuildingFeature]) -> PropertyTable {
    let strings =
        |f: &dyn Fn(&BuildingFeature) -> String| Column::Strings(features.iter().map(f).collect());
    let floats =
        |f: &dyn Fn(&BuildingFeature) -> f32| Column::Float32(features.iter().map(f).collect());
    // Written under citymesh's names and again under Cesium OSM Buildings'.
    let types = strings(&|f| match f.id {
        OsmId::Way(_) => "way".into(),
        OsmId::Relation(_) => "relation".into(),
    });
    let ids = Column::Int64(
        features
            .iter()
            .map(|f| match f.id {
                OsmId::Way(id) | OsmId::Relation(id) => id,
            })
            .collect(),
    );
    PropertyTable {
        class: &BUILDING_CLASS,
        columns: vec![
            types.clone(),
            ids.clone(),
            strings(&|f| f.building.clone()),
            strings(&|f| f.name.clone().unwrap_or_default()),
            strings(&|f| f.address.clone().unwrap_or_default()),
            floats(&|f| f.height as f32),
            floats(&|f| f.min_height as f32),
            floats(&|f| f.levels.map_or(-1.0, |l| l as f32)),
            strings(&|f| f.roof_shape.into()),
            strings(&|f| f.roof_origin.name().into()),
            floats(&|f| match f.roof_origin {
                RoofOrigin::Classifier { probability } | RoofOrigin::Inferred { probability } => {
                    probability
                }
                _ => -1.0,
            }),
            strings(&|f| f.wall_colour.hex()),
            strings(&|f| f.roof_colour.hex()),
            ids,
            types,
            floats(&|f| f.height as f32),
            Column::Float64(features.iter().map(|f| f.centre[1]).collect()),
            Column::Float64(features.iter().map(|f| f.centre[0]).collect()),
            strings(&|f| f.osm_tags.clone().unwrap_or_default()),
            Column::Booleans(features.iter().map(|f| f.quality.closed).collect()),
            Column::Booleans(features.iter().map(|f| f.quality.strict_manifold).collect()),
            strings(&|f| f.quality.repairs.join(",")),
            floats(&|f| f.quality.floor_area as f32),
            floats(&|f| f.quality.outline_area as f32),
        ],
    }
}

/// The probability a [`crate::scene::RoofChoice`] recorded, if the shape was chosen.
fn chosen_probability(tags: &Tags) -> Option<f32> {
    let p: f32 = tags.get(CHOSEN_ROOF_PROBABILITY)?.parse().ok()?;
    (0.0..=1.0).contains(&p).then_some(p)
}

/// `addr:street addr:housenumber, addr:postcode addr:city`, with what is tagged.
fn address(tags: &Tags) -> Option<String> {
    let get = |k: &str| tags.get(k).map(|v| v.trim()).filter(|v| !v.is_empty());
    let join = |a: Option<&str>, b: Option<&str>| match (a, b) {
        (Some(a), Some(b)) => Some(format!("{a} {b}")),
        (a, b) => a.or(b).map(str::to_owned),
    };
    let street = join(get("addr:street"), get("addr:housenumber"));
    let place = join(get("addr:postcode"), get("addr:city"));
    match (street, place) {
        (Some(s), Some(p)) => Some(format!("{s}, {p}")),
        (s, p) => s.or(p),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(tags: &[(&str, &str)]) -> BuildingRecord {
        BuildingRecord {
            id: OsmId::Way(42),
            is_part: false,
            outers: Vec::new(),
            inners: Vec::new(),
            tags: tags
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
        }
    }

    fn feature(tags: &[(&str, &str)]) -> BuildingFeature {
        let r = record(tags);
        let t = BuildingTags::read(&r.tags);
        let p = BuildingParams::new(&t, 5.0);
        BuildingFeature::new(&r, &t, &p)
    }

    #[test]
    fn tags_become_the_row_a_client_sees() {
        let f = feature(&[
            ("building", "house"),
            ("name", "Haus Kirchfeld"),
            ("addr:street", "Lindenallee"),
            ("addr:housenumber", "7"),
            ("addr:city", "Karlsruhe"),
            ("building:levels", "2"),
            ("height", "9.5"),
            ("roof:shape", "gabled"),
        ]);
        assert_eq!(f.building, "house");
        assert_eq!(f.name.as_deref(), Some("Haus Kirchfeld"));
        assert_eq!(f.address.as_deref(), Some("Lindenallee 7, Karlsruhe"));
        assert_eq!(f.height, 9.5);
        assert_eq!(f.levels, Some(2.0));
        assert_eq!(f.roof_shape, "gabled");
        assert_eq!(f.roof_origin, RoofOrigin::Tag);
    }

    #[test]
    fn a_chosen_shape_says_so_with_its_probability_and_an_untagged_roof_is_the_default() {
        let f = feature(&[
            ("building", "yes"),
            ("roof:shape", "hipped"),
            (CHOSEN_ROOF_PROBABILITY, "0.875"),
        ]);
        assert_eq!(f.roof_shape, "hipped");
        assert_eq!(f.roof_origin, RoofOrigin::Classifier { probability: 0.875 });
        let d = feature(&[("building", "yes")]);
        assert_eq!((d.roof_shape, d.roof_origin), ("flat", RoofOrigin::Default));
        assert_eq!((d.name, d.address, d.levels), (None, None, None));
        let odd = feature(&[("building", "yes"), ("roof:shape", "zakomar")]);
        assert_eq!(odd.roof_origin, RoofOrigin::Default);
        let inferred = feature(&[
            ("building", "yes"),
            ("roof:shape", "gabled"),
            (CHOSEN_ROOF_PROBABILITY, "0.75"),
            (CHOSEN_ROOF_ORIGIN, INFERRED),
        ]);
        assert_eq!(
            inferred.roof_origin,
            RoofOrigin::Inferred { probability: 0.75 }
        );
        assert_eq!(inferred.roof_origin.name(), "inferred");
        // An origin without a probability is no chosen shape.
        let bare = feature(&[("roof:shape", "gabled"), (CHOSEN_ROOF_ORIGIN, INFERRED)]);
        assert_eq!(bare.roof_origin, RoofOrigin::Tag);
    }

    #[test]
    fn the_table_has_a_column_per_property_and_a_row_per_building() {
        let rows = [
            feature(&[("building", "house"), ("building:colour", "#ff0000")]),
            feature(&[
                ("building", "yes"),
                ("roof:shape", "gabled"),
                (CHOSEN_ROOF_PROBABILITY, "0.5"),
            ]),
        ];
        let t = property_table(&rows);
        assert_eq!(t.columns.len(), BUILDING_CLASS.properties.len());
        assert_eq!(t.count(), 2);
        assert_eq!(t.columns[1], Column::Int64(vec![42, 42]));
        assert_eq!(
            t.columns[9],
            Column::Strings(vec!["default".into(), "classifier".into()])
        );
        assert_eq!(t.columns[10], Column::Float32(vec![-1.0, 0.5]));
        assert_eq!(
            t.columns[11],
            Column::Strings(vec!["#ff0000".into(), rows[1].wall_colour.hex()])
        );
    }
}

//! What the roof prior knows of one building: its outline's shape and size, and its tags. A
//! missing value is NaN (the trees send it to its own side of every split).

use crate::building::axes::RoofAxes;
use crate::building::footprint::signed_area;
use crate::building::tags::{parse_length, parse_levels};
use crate::geo::LocalFrame;
use crate::osm::BuildingRecord;

/// `building` values with a column of their own; the rest share `building=other`.
pub const BUILDING_VALUES: [&str; 22] = [
    "yes",
    "house",
    "detached",
    "semidetached_house",
    "terrace",
    "residential",
    "apartments",
    "garage",
    "garages",
    "carport",
    "shed",
    "roof",
    "commercial",
    "retail",
    "industrial",
    "warehouse",
    "office",
    "school",
    "church",
    "farm_auxiliary",
    "barn",
    "hut",
];

/// `roof:material` values that mostly cover pitched roofs.
const PITCHED_MATERIALS: [&str; 7] = [
    "roof_tiles",
    "tiles",
    "tile",
    "clay",
    "slate",
    "eternit",
    "thatch",
];
/// `roof:material` values that mostly cover flat roofs.
const FLAT_MATERIALS: [&str; 10] = [
    "concrete",
    "tar_paper",
    "gravel",
    "asphalt",
    "bitumen",
    "roofing_felt",
    "grass",
    "plants",
    "pebblestone",
    "asphalt_shingle",
];

/// The names of the outline and tag columns, in order.
pub fn own_feature_names() -> Vec<String> {
    let mut names: Vec<String> = [
        "log_area_m2",
        "elongation",
        "rectangle_fill",
        "outline_nodes",
        "courtyards",
        "building_levels",
        "roof_levels",
        "height_m",
        "pitch_tags",
        "roof_colour_tagged",
        "roof_material_pitched",
        "roof_material_flat",
        "roof_material_other",
        "address_tagged",
        "name_tagged",
        "amenity_or_shop_tagged",
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .collect();
    names.extend(BUILDING_VALUES.iter().map(|v| format!("building={v}")));
    names.push("building=other".to_owned());
    names
}

/// A building's outline in the area's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outline {
    /// The centroid of the outer ring's vertices, metres.
    pub centre: [f64; 2],
    /// Square metres (courtyards taken out).
    pub area: f64,
    /// The virtual rectangle's long side over its short side.
    pub elongation: f64,
    /// The area over the virtual rectangle's.
    pub fill: f64,
    /// The direction of the long side, radians in [0, pi).
    pub axis: f64,
}

impl Outline {
    /// The outline of `record`'s first outer ring in `frame`; `None` without area.
    pub fn of(record: &BuildingRecord, frame: &LocalFrame) -> Option<Self> {
        let outer = record.outers.first()?.local_points(frame);
        if outer.len() < 3 {
            return None;
        }
        let holes: f64 = record
            .inners
            .iter()
            .map(|r| signed_area(&r.local_points(frame)).abs())
            .sum();
        let area = (signed_area(&outer).abs() - holes).max(0.0);
        let axes = RoofAxes::of_ring(&outer)?.long_first();
        if !(area > 0.1 && axes.rx > 0.0 && axes.ry > 0.0) {
            return None;
        }
        let n = outer.len() as f64;
        let centre = outer
            .iter()
            .fold([0.0, 0.0], |c, p| [c[0] + p[0] / n, c[1] + p[1] / n]);
        // x' runs along `n`, and x' is the long axis.
        let axis = axes.n[1].atan2(axes.n[0]).rem_euclid(std::f64::consts::PI);
        Some(Self {
            centre,
            area,
            elongation: axes.rx / axes.ry,
            fill: (area / (4.0 * axes.rx * axes.ry)).min(1.0),
            axis,
        })
    }
}

fn flag(b: bool) -> f32 {
    if b { 1.0 } else { 0.0 }
}

fn optional(v: Option<f64>) -> f32 {
    v.map_or(f32::NAN, |v| v as f32)
}

/// The outline and tag columns of a building (see [`own_feature_names`]).
pub fn own_features(record: &BuildingRecord, outline: &Outline) -> Vec<f32> {
    let tags = &record.tags;
    let get = |k: &str| tags.get(k).map(|v| v.trim()).filter(|v| !v.is_empty());
    let material = get("roof:material");
    let pitched_material = material.is_some_and(|m| PITCHED_MATERIALS.contains(&m));
    let flat_material = material.is_some_and(|m| FLAT_MATERIALS.contains(&m));
    let pitch_tags = [
        "roof:angle",
        "roof:height",
        "roof:orientation",
        "roof:direction",
    ]
    .iter()
    .any(|k| get(k).is_some());
    let nodes = record.outers.first().map_or(0, |r| r.nodes.len());
    let mut row = vec![
        outline.area.max(1.0).ln() as f32,
        outline.elongation as f32,
        outline.fill as f32,
        nodes as f32,
        record.inners.len() as f32,
        optional(get("building:levels").and_then(parse_levels)),
        optional(get("roof:levels").and_then(parse_levels)),
        optional(get("height").and_then(parse_length)),
        flag(pitch_tags),
        flag(get("roof:colour").is_some()),
        flag(pitched_material),
        flag(flat_material),
        flag(material.is_some() && !pitched_material && !flat_material),
        flag(get("addr:housenumber").is_some()),
        flag(get("name").is_some()),
        flag(get("amenity").is_some() || get("shop").is_some()),
    ];
    let value = get("building").unwrap_or("yes");
    let known = BUILDING_VALUES.iter().position(|v| *v == value);
    row.extend((0..BUILDING_VALUES.len()).map(|i| flag(known == Some(i))));
    row.push(flag(known.is_none()));
    row
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rectangle(id: i64, w: f64, h: f64, tags: &[(&str, &str)]) -> crate::osm::BuildingRecord {
        crate::roof_prior::tests::building(id, [0.0, 0.0], w, h, tags)
    }

    #[test]
    fn a_rectangle_has_its_area_elongation_and_full_fill() {
        let r = rectangle(1, 20.0, 10.0, &[("building", "house")]);
        let frame = LocalFrame::new(8.4, 49.0, 0.0);
        let o = Outline::of(&r, &frame).unwrap();
        assert!((o.area - 200.0).abs() < 0.01, "{o:?}");
        assert!((o.elongation - 2.0).abs() < 1e-3);
        assert!((o.fill - 1.0).abs() < 1e-3);
        assert!(o.axis.abs() < 1e-3 || (o.axis - std::f64::consts::PI).abs() < 1e-3);
        let f = own_features(&r, &o);
        assert_eq!(f.len(), own_feature_names().len());
        assert!((f[0] - 200f32.ln()).abs() < 1e-4);
        assert!(f[5].is_nan() && f[6].is_nan() && f[7].is_nan());
        let house = own_feature_names()
            .iter()
            .position(|n| n == "building=house")
            .unwrap();
        assert_eq!(f[house], 1.0);
        assert_eq!(f.iter().skip(16).sum::<f32>(), 1.0);
    }

    #[test]
    fn tags_fill_their_columns() {
        let r = rectangle(
            2,
            12.0,
            12.0,
            &[
                ("building", "bunker"),
                ("building:levels", "3"),
                ("roof:levels", "1"),
                ("height", "12 m"),
                ("roof:material", "roof_tiles"),
                ("roof:orientation", "across"),
                ("addr:housenumber", "5"),
            ],
        );
        let o = Outline::of(&r, &LocalFrame::new(8.4, 49.0, 0.0)).unwrap();
        let f = own_features(&r, &o);
        assert_eq!(&f[5..14], &[3.0, 1.0, 12.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        assert_eq!(*f.last().unwrap(), 1.0, "bunker is building=other");
    }
}

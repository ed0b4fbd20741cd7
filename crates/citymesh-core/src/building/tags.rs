//! Reading building tags leniently: "12 m", "9.0", "12;15", "40'" and compass letters are
//! understood; nonsense ("tall", negative, NaN, absurdly large) is ignored and reported, so the
//! fallback takes over and the statistics count it.

use super::roof::RoofShape;
use crate::mesh::Rgb;
use crate::osm::Tags;

/// What `roof:shape` says.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeTag {
    Missing,
    Known(RoofShape),
    /// A value naming no shape citymesh draws (rendered flat and counted).
    Unsupported(String),
}

/// What `roof:orientation` says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Orientation {
    /// The ridge runs along the longest side (OSM's default).
    #[default]
    Along,
    /// The ridge is turned 90 degrees.
    Across,
}

/// The building tags citymesh uses, parsed.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BuildingTags {
    pub building_type: String,
    pub height: Option<f64>,
    pub min_height: Option<f64>,
    pub levels: Option<f64>,
    pub min_level: Option<f64>,
    pub roof_levels: Option<f64>,
    pub roof_height: Option<f64>,
    pub roof_angle: Option<f64>,
    pub roof_shape: Option<ShapeTag>,
    pub orientation: Orientation,
    pub direction: Option<f64>,
    pub building_colour: Option<Rgb>,
    pub roof_colour: Option<Rgb>,
    pub building_material: Option<String>,
    pub roof_material: Option<String>,
    /// Keys whose values were present but unusable.
    pub invalid: Vec<&'static str>,
}

/// The keys [`BuildingTags::read`] looks at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Building,
    BuildingPart,
    Height,
    MinHeight,
    Levels,
    MinLevel,
    RoofLevels,
    RoofHeight,
    RoofAngle,
    RoofDirection,
    RoofShape,
    RoofOrientation,
    BuildingColour,
    RoofColour,
    BuildingMaterial,
    RoofMaterial,
}

impl Key {
    const ALL: [Key; 16] = [
        Key::Building,
        Key::BuildingPart,
        Key::Height,
        Key::MinHeight,
        Key::Levels,
        Key::MinLevel,
        Key::RoofLevels,
        Key::RoofHeight,
        Key::RoofAngle,
        Key::RoofDirection,
        Key::RoofShape,
        Key::RoofOrientation,
        Key::BuildingColour,
        Key::RoofColour,
        Key::BuildingMaterial,
        Key::RoofMaterial,
    ];
    const COUNT: usize = Key::ALL.len();

    /// The key an OSM tag key names, if it is one of them.
    fn of(key: &str) -> Option<Self> {
        // Most other keys (addr:*, name, source, ...) fail on the first byte; the rest compare
        // lengths before bytes.
        if !matches!(key.as_bytes().first(), Some(b'b' | b'h' | b'm' | b'r')) {
            return None;
        }
        Key::ALL.into_iter().find(|k| k.name() == key)
    }

    /// The OSM key, as reported among invalid tags.
    fn name(self) -> &'static str {
        match self {
            Key::Building => "building",
            Key::BuildingPart => "building:part",
            Key::Height => "height",
            Key::MinHeight => "min_height",
            Key::Levels => "building:levels",
            Key::MinLevel => "building:min_level",
            Key::RoofLevels => "roof:levels",
            Key::RoofHeight => "roof:height",
            Key::RoofAngle => "roof:angle",
            Key::RoofDirection => "roof:direction",
            Key::RoofShape => "roof:shape",
            Key::RoofOrientation => "roof:orientation",
            Key::BuildingColour => "building:colour",
            Key::RoofColour => "roof:colour",
            Key::BuildingMaterial => "building:material",
            Key::RoofMaterial => "roof:material",
        }
    }
}

impl BuildingTags {
    pub fn read(tags: &Tags) -> Self {
        // One pass over the tags picks out the keys read below (cheaper than a lookup per key).
        let mut found: [Option<&String>; Key::COUNT] = [None; Key::COUNT];
        for (key, value) in tags {
            if let Some(k) = Key::of(key) {
                found[k as usize] = Some(value);
            }
        }
        let get = |key: Key| found[key as usize];
        let mut t = BuildingTags {
            building_type: get(Key::Building)
                .filter(|v| v.as_str() != "no")
                .or_else(|| get(Key::BuildingPart))
                .cloned()
                .unwrap_or_default(),
            ..Default::default()
        };
        let mut take = |key: Key, parse: fn(&str) -> Option<f64>| -> Option<f64> {
            let value = get(key)?;
            let parsed = parse(value);
            if parsed.is_none() {
                t.invalid.push(key.name());
            }
            parsed
        };
        let height = take(Key::Height, parse_length);
        let min_height = take(Key::MinHeight, parse_length);
        let levels = take(Key::Levels, parse_levels);
        let min_level = take(Key::MinLevel, parse_levels);
        let roof_levels = take(Key::RoofLevels, parse_levels);
        let roof_height = take(Key::RoofHeight, parse_length);
        let roof_angle = take(Key::RoofAngle, parse_angle);
        let direction = take(Key::RoofDirection, parse_direction);
        t.height = height;
        t.min_height = min_height;
        t.levels = levels;
        t.min_level = min_level;
        t.roof_levels = roof_levels;
        t.roof_height = roof_height;
        t.roof_angle = roof_angle;
        t.direction = direction;
        t.roof_shape = get(Key::RoofShape).map(|v| match RoofShape::from_tag(v) {
            Some(s) => ShapeTag::Known(s),
            None => ShapeTag::Unsupported(v.clone()),
        });
        match get(Key::RoofOrientation).map(|v| v.trim()) {
            None => {}
            Some("along") => t.orientation = Orientation::Along,
            Some("across") => t.orientation = Orientation::Across,
            Some(_) => t.invalid.push("roof:orientation"),
        }
        for (key, slot) in [
            (Key::BuildingColour, &mut t.building_colour),
            (Key::RoofColour, &mut t.roof_colour),
        ] {
            if let Some(v) = get(key) {
                *slot = parse_colour(v);
                if slot.is_none() {
                    t.invalid.push(key.name());
                }
            }
        }
        t.building_material = get(Key::BuildingMaterial).cloned();
        t.roof_material = get(Key::RoofMaterial).cloned();
        t
    }
}

/// The first of several values ("12;15" -> "12").
fn first(value: &str) -> &str {
    value.split(';').next().unwrap_or_default().trim()
}

fn finite_in(v: f64, lo: f64, hi: f64) -> Option<f64> {
    (v.is_finite() && v >= lo && v <= hi).then_some(v)
}

/// A length in metres: "12", "12.5 m", "12,5", "40 ft", "40'", "12'6\"".
pub fn parse_length(value: &str) -> Option<f64> {
    let v = first(value);
    let max = super::defaults::MAX_HEIGHT;
    if let Some((feet, rest)) = v.split_once('\'') {
        let inches = rest.trim().trim_end_matches('"').trim();
        let inches = if inches.is_empty() {
            0.0
        } else {
            inches.parse::<f64>().ok()?
        };
        return finite_in(
            (feet.trim().parse::<f64>().ok()? * 12.0 + inches) * 0.0254,
            0.0,
            max,
        );
    }
    let (number, factor) = if let Some(n) = v.strip_suffix("ft") {
        (n, 0.3048)
    } else if let Some(n) = v.strip_suffix("feet") {
        (n, 0.3048)
    } else if let Some(n) = v
        .strip_suffix("meters")
        .or_else(|| v.strip_suffix("metres"))
    {
        (n, 1.0)
    } else if let Some(n) = v.strip_suffix('m') {
        (n, 1.0)
    } else {
        (v, 1.0)
    };
    let number = number.trim();
    let parsed = number.parse::<f64>().ok().or_else(|| {
        // A decimal comma, "12,5", when it is the only separator.
        (number.matches(',').count() == 1 && !number.contains('.'))
            .then(|| number.replace(',', ".").parse::<f64>().ok())
            .flatten()
    })?;
    finite_in(parsed * factor, 0.0, max)
}

/// A number of storeys: "3", "2.5"; 0..=300.
pub fn parse_levels(value: &str) -> Option<f64> {
    finite_in(first(value).parse::<f64>().ok()?, 0.0, 300.0)
}

/// A roof angle in degrees, 0 up to (not including) 90: "30", "30°", "30 deg".
pub fn parse_angle(value: &str) -> Option<f64> {
    let v = first(value)
        .trim_end_matches("deg")
        .trim_end_matches('°')
        .trim();
    finite_in(v.parse::<f64>().ok()?, 0.0, 89.0)
}

/// A compass direction in degrees clockwise from north: "135", "SE", "NNW".
pub fn parse_direction(value: &str) -> Option<f64> {
    const POINTS: [&str; 16] = [
        "N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE", "S", "SSW", "SW", "WSW", "W", "WNW",
        "NW", "NNW",
    ];
    let v = first(value);
    if let Some(i) = POINTS.iter().position(|p| p.eq_ignore_ascii_case(v)) {
        return Some(i as f64 * 22.5);
    }
    let d = v.trim_end_matches('°').trim().parse::<f64>().ok()?;
    d.is_finite().then(|| d.rem_euclid(360.0))
}

/// A CSS colour: names, #rgb, #rrggbb, rgb(...).
pub fn parse_colour(value: &str) -> Option<Rgb> {
    let c = csscolorparser::parse(first(value)).ok()?;
    let [r, g, b, _] = c.to_rgba8();
    Some(Rgb(r, g, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn every_key_is_found_by_its_name_and_nothing_else_is() {
        assert_eq!(Key::COUNT, Key::RoofMaterial as usize + 1);
        for (i, key) in Key::ALL.into_iter().enumerate() {
            assert_eq!(key as usize, i);
            assert_eq!(Key::of(key.name()), Some(key));
        }
        for other in [
            "",
            "b",
            "name",
            "addr:street",
            "roof:shapes",
            "Height",
            "building:",
        ] {
            assert_eq!(Key::of(other), None, "{other}");
        }
    }

    #[rstest]
    #[case("12", Some(12.0))]
    #[case("12 m", Some(12.0))]
    #[case("9.0", Some(9.0))]
    #[case("12;15", Some(12.0))]
    #[case("12,5", Some(12.5))]
    #[case("10 ft", Some(3.048))]
    #[case("10'", Some(3.048))]
    #[case("10'6\"", Some(3.2004))]
    #[case("tall", None)]
    #[case("-3", None)]
    #[case("NaN", None)]
    #[case("inf", None)]
    #[case("1e9", None)]
    #[case("", None)]
    fn lengths(#[case] text: &str, #[case] expected: Option<f64>) {
        match (parse_length(text), expected) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-9, "{text}: {a}"),
            (a, b) => assert_eq!(a, b, "{text}"),
        }
    }

    #[rstest]
    #[case("N", Some(0.0))]
    #[case("nne", Some(22.5))]
    #[case("SE", Some(135.0))]
    #[case("WNW", Some(292.5))]
    #[case("370", Some(10.0))]
    #[case("-90", Some(270.0))]
    #[case("up", None)]
    fn directions(#[case] text: &str, #[case] expected: Option<f64>) {
        assert_eq!(parse_direction(text), expected);
    }

    #[test]
    fn colours_and_invalid_values() {
        assert_eq!(parse_colour("red"), Some(Rgb(255, 0, 0)));
        assert_eq!(parse_colour("#abc"), Some(Rgb(0xaa, 0xbb, 0xcc)));
        assert_eq!(parse_colour("#a0522d"), Some(Rgb(0xa0, 0x52, 0x2d)));
        assert_eq!(parse_colour("bluish"), None);
        let tags: Tags = [
            ("building", "house"),
            ("height", "tall"),
            ("roof:colour", "bluish"),
            ("roof:shape", "gabled"),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect();
        let t = BuildingTags::read(&tags);
        assert_eq!(t.height, None);
        assert_eq!(t.invalid, vec!["height", "roof:colour"]);
        assert_eq!(t.roof_shape, Some(ShapeTag::Known(RoofShape::Gabled)));
        assert_eq!(t.building_type, "house");
    }
}

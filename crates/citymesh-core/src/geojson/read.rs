//! Reading a user's GeoJSON FeatureCollection of buildings, checking everything: the document's
//! shape, geometry types, closed and simple rings, coordinates in range, property values, and
//! the size limits. Every error names the feature (by index) and the field, and says what to fix.

use crate::building::footprint::{
    Footprint, FootprintError, FootprintRing, MAX_FOOTPRINT_VERTICES, MAX_HOLES,
};
use crate::building::roof::RoofShape;
use crate::building::tags::{parse_colour, parse_direction, parse_length, parse_levels};
use crate::geo::{GeoBbox, LocalFrame, MAX_MERCATOR_LAT};
use crate::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use serde_json::Value;

/// What a request may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GeoJsonLimits {
    pub max_features: usize,
    /// Positions over all features.
    pub max_vertices: usize,
}

impl Default for GeoJsonLimits {
    fn default() -> Self {
        Self {
            max_features: 20_000,
            max_vertices: 1_000_000,
        }
    }
}

/// The kind of problem, which decides the HTTP status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GeoJsonErrorKind {
    /// Not JSON at all.
    NotJson,
    /// More features or vertices than allowed (413).
    TooLarge,
    /// Valid JSON that is not a usable building collection (422).
    Invalid,
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}{field}: {message}", .feature.map(|i| format!("features[{i}].")).unwrap_or_default())]
pub struct GeoJsonError {
    pub kind: GeoJsonErrorKind,
    /// Index of the offending feature, when one is to blame.
    pub feature: Option<usize>,
    /// The field inside it (or the document), e.g. `geometry.coordinates[0]`.
    pub field: String,
    pub message: String,
}

/// The buildings of a collection and its `bbox` member, if it has one.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoJsonScene {
    pub records: Vec<BuildingRecord>,
    pub bbox: Option<GeoBbox>,
}

fn invalid(
    feature: Option<usize>,
    field: impl Into<String>,
    message: impl Into<String>,
) -> GeoJsonError {
    GeoJsonError {
        kind: GeoJsonErrorKind::Invalid,
        feature,
        field: field.into(),
        message: message.into(),
    }
}

/// Reads and checks a FeatureCollection.
pub fn read_geojson(bytes: &[u8], limits: GeoJsonLimits) -> Result<GeoJsonScene, GeoJsonError> {
    let doc: Value = serde_json::from_slice(bytes).map_err(|e| GeoJsonError {
        kind: GeoJsonErrorKind::NotJson,
        feature: None,
        field: "body".into(),
        message: format!("not JSON ({e}); send a GeoJSON FeatureCollection"),
    })?;
    if doc.get("type").and_then(Value::as_str) != Some("FeatureCollection") {
        return Err(invalid(
            None,
            "type",
            "the document must be a GeoJSON FeatureCollection ({\"type\": \"FeatureCollection\", \"features\": [...]})",
        ));
    }
    let features = doc
        .get("features")
        .and_then(Value::as_array)
        .ok_or_else(|| invalid(None, "features", "must be an array of Features"))?;
    if features.len() > limits.max_features {
        return Err(GeoJsonError {
            kind: GeoJsonErrorKind::TooLarge,
            feature: None,
            field: "features".into(),
            message: format!(
                "{} features, more than the limit of {}; split the collection",
                features.len(),
                limits.max_features
            ),
        });
    }
    let bbox = match doc.get("bbox") {
        None | Some(Value::Null) => None,
        Some(b) => Some(read_bbox(b)?),
    };
    let mut vertices = 0usize;
    let mut records = Vec::with_capacity(features.len());
    for (i, f) in features.iter().enumerate() {
        let record = read_feature(i, f, &mut vertices, limits)?;
        if let Some(b) = &bbox {
            let outside = record
                .outers
                .iter()
                .flat_map(|r| &r.nodes)
                .any(|n| !b.contains(n.lon, n.lat));
            if outside {
                return Err(invalid(
                    Some(i),
                    "geometry",
                    "lies outside the collection's bbox; widen the bbox or drop it",
                ));
            }
        }
        records.push(record);
    }
    Ok(GeoJsonScene { records, bbox })
}

fn read_bbox(b: &Value) -> Result<GeoBbox, GeoJsonError> {
    let v: Option<Vec<f64>> = b
        .as_array()
        .and_then(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<f64>>>());
    match v.as_deref() {
        Some([w, s, e, n]) => {
            GeoBbox::new(*w, *s, *e, *n).map_err(|e| invalid(None, "bbox", format!("{e}")))
        }
        _ => Err(invalid(
            None,
            "bbox",
            "must be [west, south, east, north] in degrees",
        )),
    }
}

fn read_id(i: usize, f: &Value) -> OsmId {
    let fallback = OsmId::Way(i as i64 + 1);
    match f.get("id") {
        Some(Value::Number(n)) => n.as_i64().map_or(fallback, OsmId::Way),
        Some(Value::String(s)) => {
            let parse = |prefix: &str| s.strip_prefix(prefix).and_then(|n| n.parse::<i64>().ok());
            parse("way/")
                .map(OsmId::Way)
                .or_else(|| parse("relation/").map(OsmId::Relation))
                .unwrap_or(fallback)
        }
        _ => fallback,
    }
}

fn read_feature(
    i: usize,
    f: &Value,
    vertices: &mut usize,
    limits: GeoJsonLimits,
) -> Result<BuildingRecord, GeoJsonError> {
    let at = Some(i);
    if f.get("type").and_then(Value::as_str) != Some("Feature") {
        return Err(invalid(at, "type", "must be \"Feature\""));
    }
    let tags = read_properties(i, f.get("properties"))?;
    let geometry = f
        .get("geometry")
        .filter(|g| !g.is_null())
        .ok_or_else(|| invalid(at, "geometry", "is missing; give a Polygon or MultiPolygon"))?;
    let kind = geometry.get("type").and_then(Value::as_str).unwrap_or("");
    let coords = geometry
        .get("coordinates")
        .and_then(Value::as_array)
        .ok_or_else(|| invalid(at, "geometry.coordinates", "must be an array"))?;
    let polygons: Vec<(&Vec<Value>, String)> = match kind {
        "Polygon" => vec![(coords, "geometry.coordinates".to_owned())],
        "MultiPolygon" => coords
            .iter()
            .enumerate()
            .map(|(k, p)| {
                p.as_array()
                    .map(|a| (a, format!("geometry.coordinates[{k}]")))
                    .ok_or_else(|| {
                        invalid(
                            at,
                            format!("geometry.coordinates[{k}]"),
                            "must be an array of rings",
                        )
                    })
            })
            .collect::<Result<_, _>>()?,
        other => {
            return Err(invalid(
                at,
                "geometry.type",
                format!("is \"{other}\"; buildings must be Polygon or MultiPolygon"),
            ));
        }
    };
    if polygons.is_empty() {
        return Err(invalid(at, "geometry.coordinates", "has no polygon"));
    }
    let mut outers = Vec::new();
    let mut inners = Vec::new();
    for (rings, field) in polygons {
        if rings.is_empty() {
            return Err(invalid(at, field, "has no ring"));
        }
        if inners.len() + rings.len() - 1 > MAX_HOLES {
            return Err(GeoJsonError {
                kind: GeoJsonErrorKind::TooLarge,
                feature: at,
                field,
                message: format!(
                    "the building has {} holes; one building may have at most {MAX_HOLES}: \
                     simplify it or split it into several features",
                    inners.len() + rings.len() - 1
                ),
            });
        }
        let mut parsed = Vec::with_capacity(rings.len());
        for (k, r) in rings.iter().enumerate() {
            let field = format!("{field}[{k}]");
            let ring = read_ring(i, &field, r)?;
            *vertices += ring.nodes.len();
            if *vertices > limits.max_vertices {
                return Err(GeoJsonError {
                    kind: GeoJsonErrorKind::TooLarge,
                    feature: at,
                    field,
                    message: format!(
                        "the collection has more than {} positions; split it",
                        limits.max_vertices
                    ),
                });
            }
            parsed.push((ring, field));
        }
        check_simple(i, &parsed)?;
        let points = outers
            .iter()
            .chain(&inners)
            .chain(parsed.iter().map(|(r, _)| r))
            .map(|r: &Ring| r.nodes.len())
            .sum::<usize>();
        if points > MAX_FOOTPRINT_VERTICES {
            return Err(GeoJsonError {
                kind: GeoJsonErrorKind::TooLarge,
                feature: at,
                field: "geometry.coordinates".to_owned(),
                message: format!(
                    "the building has {points} positions; one building may have at most \
                     {MAX_FOOTPRINT_VERTICES}: simplify it or split it into several features"
                ),
            });
        }
        let mut it = parsed.into_iter().map(|(r, _)| r);
        outers.extend(it.next());
        inners.extend(it);
    }
    let is_part = tags.contains_key("building:part") && !tags.contains_key("building");
    Ok(BuildingRecord {
        id: read_id(i, f),
        is_part,
        outers,
        inners,
        tags,
    })
}

/// A ring: at least four positions, closed, each [lon, lat] (or with a height) in range. Stored
/// open, as the rest of citymesh keeps rings.
fn read_ring(i: usize, field: &str, r: &Value) -> Result<Ring, GeoJsonError> {
    let at = Some(i);
    let positions = r
        .as_array()
        .ok_or_else(|| invalid(at, field, "must be an array of [lon, lat] positions"))?;
    if positions.len() < 4 {
        return Err(invalid(
            at,
            field,
            format!(
                "has {} positions; a ring needs at least 4, the last repeating the first",
                positions.len()
            ),
        ));
    }
    let mut nodes = Vec::with_capacity(positions.len());
    for (k, p) in positions.iter().enumerate() {
        let c: Option<Vec<f64>> = p
            .as_array()
            .and_then(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<f64>>>());
        let (lon, lat) = match c.as_deref() {
            Some([lon, lat] | [lon, lat, _]) => (*lon, *lat),
            _ => {
                return Err(invalid(
                    at,
                    format!("{field}[{k}]"),
                    "must be [lon, lat] numbers",
                ));
            }
        };
        if !(-180.0..=180.0).contains(&lon)
            || !(-MAX_MERCATOR_LAT..=MAX_MERCATOR_LAT).contains(&lat)
        {
            return Err(invalid(
                at,
                format!("{field}[{k}]"),
                format!("[{lon}, {lat}] is out of range: lon -180..180, lat -85.0511..85.0511"),
            ));
        }
        nodes.push(RingNode { id: None, lon, lat });
    }
    let (first, last) = (nodes[0], nodes[nodes.len() - 1]);
    if first.lon != last.lon || first.lat != last.lat {
        return Err(invalid(
            at,
            field,
            "is not closed: its last position must repeat the first",
        ));
    }
    nodes.pop();
    Ok(Ring { nodes })
}

/// Rings may not cross themselves, and must have an area.
fn check_simple(i: usize, rings: &[(Ring, String)]) -> Result<(), GeoJsonError> {
    let Some(first) = rings.first().and_then(|(r, _)| r.nodes.first()) else {
        return Ok(());
    };
    let frame = LocalFrame::new(first.lon, first.lat, 0.0);
    for (r, field) in rings {
        let points = r.local_points(&frame);
        match Footprint::new(FootprintRing::from_points(points), vec![]) {
            Ok(_) => {}
            Err(FootprintError::SelfIntersecting) => {
                return Err(invalid(
                    Some(i),
                    field.clone(),
                    "crosses itself; fix the ring's order of positions",
                ));
            }
            Err(e) => {
                return Err(invalid(
                    Some(i),
                    field.clone(),
                    format!("is not a usable ring: {e}"),
                ));
            }
        }
    }
    Ok(())
}

/// Properties become OSM tags; the ones citymesh reads are checked.
fn read_properties(i: usize, p: Option<&Value>) -> Result<Tags, GeoJsonError> {
    let at = Some(i);
    let mut tags = Tags::new();
    match p {
        None | Some(Value::Null) => {}
        Some(Value::Object(map)) => {
            for (k, v) in map {
                let value = match v {
                    Value::String(s) => s.clone(),
                    Value::Number(n) => n.to_string(),
                    Value::Bool(b) => if *b { "yes" } else { "no" }.to_owned(),
                    Value::Null => continue,
                    _ => {
                        return Err(invalid(
                            at,
                            format!("properties.{k}"),
                            "must be a string, number or boolean",
                        ));
                    }
                };
                tags.insert(k.clone(), value);
            }
        }
        Some(_) => return Err(invalid(at, "properties", "must be an object")),
    }
    let check = |key: &str, ok: bool, what: &str| -> Result<(), GeoJsonError> {
        if ok {
            Ok(())
        } else {
            Err(invalid(
                at,
                format!("properties.{key}"),
                format!(
                    "'{}' is not {what}",
                    tags.get(key).map_or("", String::as_str)
                ),
            ))
        }
    };
    let length = "a length in metres from 0 to 1000";
    for key in ["height", "min_height", "roof:height"] {
        if let Some(v) = tags.get(key) {
            check(key, parse_length(v).is_some(), length)?;
        }
    }
    if let Some(v) = tags.get("building:levels") {
        check(
            "building:levels",
            parse_levels(v).is_some(),
            "a number of levels from 0 to 300",
        )?;
    }
    if let Some(v) = tags.get("roof:direction") {
        check(
            "roof:direction",
            parse_direction(v).is_some(),
            "a direction (degrees or N, NNE, ...)",
        )?;
    }
    if let Some(v) = tags.get("roof:orientation") {
        check(
            "roof:orientation",
            v == "along" || v == "across",
            "'along' or 'across'",
        )?;
    }
    for key in ["building:colour", "roof:colour"] {
        if let Some(v) = tags.get(key) {
            check(
                key,
                parse_colour(v).is_some(),
                "a CSS colour (a name, #rgb or #rrggbb)",
            )?;
        }
    }
    if let Some(v) = tags.get("roof:shape") {
        let names: Vec<&str> = RoofShape::ALL.iter().map(|s| s.tag()).collect();
        check(
            "roof:shape",
            RoofShape::from_tag(v).is_some(),
            &format!("one of {}", names.join(", ")),
        )?;
    }
    if let (Some(h), Some(m)) = (
        tags.get("height").and_then(|v| parse_length(v)),
        tags.get("min_height").and_then(|v| parse_length(v)),
    ) && m >= h
    {
        return Err(invalid(
            at,
            "properties.min_height",
            format!("{m} is not below the height {h}"),
        ));
    }
    if !tags.contains_key("building") && !tags.contains_key("building:part") {
        tags.insert("building".into(), "yes".into());
    }
    Ok(tags)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(doc: &str) -> Result<GeoJsonScene, GeoJsonError> {
        read_geojson(doc.as_bytes(), GeoJsonLimits::default())
    }

    const SQUARE: &str = "[[[8.4,49.0],[8.401,49.0],[8.401,49.001],[8.4,49.001],[8.4,49.0]]]";

    #[test]
    fn a_polygon_with_properties_becomes_a_building() {
        let doc = format!(
            r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","id":"way/7","properties":{{"height":12,"roof:shape":"gabled"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}}]}}"#
        );
        let s = read(&doc).unwrap();
        assert_eq!(s.records.len(), 1);
        let r = &s.records[0];
        assert_eq!(r.id, OsmId::Way(7));
        assert_eq!(r.outers[0].nodes.len(), 4);
        assert_eq!(r.tags["height"], "12");
        assert_eq!(r.tags["building"], "yes");
    }

    #[test]
    fn errors_name_the_feature_and_the_field() {
        let doc = format!(
            r#"{{"type":"FeatureCollection","features":[{{"type":"Feature","properties":{{}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}},{{"type":"Feature","properties":{{"height":"1e9"}},"geometry":{{"type":"Polygon","coordinates":{SQUARE}}}}}]}}"#
        );
        let e = read(&doc).unwrap_err();
        assert_eq!(e.kind, GeoJsonErrorKind::Invalid);
        assert_eq!(e.feature, Some(1));
        assert_eq!(
            e.to_string(),
            "features[1].properties.height: '1e9' is not a length in metres from 0 to 1000"
        );
    }
}

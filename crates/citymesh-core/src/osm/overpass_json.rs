//! Overpass API JSON: `{"elements": [...]}` with nodes, ways and relations; ways and members may
//! carry inline `geometry` (`out geom;`) instead of, or besides, node ids.

use super::OsmError;
use super::raw::{Member, MemberKind, RawOsm, RawRelation, RawWay, Tags};
use serde::de::{self, DeserializeSeed, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};
use std::fmt;

#[derive(Deserialize)]
struct Point {
    lat: Option<f64>,
    lon: Option<f64>,
}

#[derive(Deserialize)]
struct JsonMember {
    #[serde(rename = "type")]
    kind: String,
    #[serde(rename = "ref")]
    id: i64,
    #[serde(default)]
    role: String,
    geometry: Option<Vec<Option<Point>>>,
}

/// What an element is; anything else (areas, derived elements) is passed over.
#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum ElementKind {
    Node,
    Way,
    Relation,
    #[serde(other)]
    Other,
}

#[derive(Deserialize)]
struct Element {
    #[serde(rename = "type")]
    kind: ElementKind,
    id: i64,
    lat: Option<f64>,
    lon: Option<f64>,
    #[serde(default)]
    nodes: Vec<i64>,
    geometry: Option<Vec<Option<Point>>>,
    #[serde(default)]
    members: Vec<JsonMember>,
    #[serde(default)]
    tags: Tags,
}

/// Inline geometry, or `None` when any point is missing (Overpass writes `null` for points outside
/// a clipped query), so the way counts as having missing nodes.
fn geometry(points: Option<Vec<Option<Point>>>) -> Option<Vec<(f64, f64)>> {
    points?
        .into_iter()
        .map(|p| p.and_then(|p| Some((p.lon?, p.lat?))))
        .collect()
}

/// Reads an Overpass JSON document. Elements are taken over one by one as they are parsed, so
/// the document's element list is never held whole.
pub fn read(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    let mut raw = RawOsm::default();
    let mut reader = serde_json::Deserializer::from_slice(bytes);
    reader
        .deserialize_map(DocumentVisitor(&mut raw))
        .and_then(|()| reader.end())
        .map_err(|e| OsmError::Json(e.to_string()))?;
    Ok(raw)
}

/// The top-level object: its `elements` go into the `RawOsm`; other keys are skipped.
struct DocumentVisitor<'a>(&'a mut RawOsm);

impl<'de> Visitor<'de> for DocumentVisitor<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an Overpass JSON object with `elements`")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = false;
        while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
            if key == "elements" {
                if seen {
                    return Err(de::Error::duplicate_field("elements"));
                }
                seen = true;
                map.next_value_seed(ElementsSeed(&mut *self.0))?;
            } else {
                map.next_value::<IgnoredAny>()?;
            }
        }
        if seen {
            Ok(())
        } else {
            Err(de::Error::missing_field("elements"))
        }
    }
}

/// The `elements` array, each element added as soon as it is read.
struct ElementsSeed<'a>(&'a mut RawOsm);

impl<'de> DeserializeSeed<'de> for ElementsSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for ElementsSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("an array of OSM elements")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(e) = seq.next_element::<Element>()? {
            add(self.0, e);
        }
        Ok(())
    }
}

fn add(raw: &mut RawOsm, e: Element) {
    match e.kind {
        ElementKind::Node => {
            if let (Some(lat), Some(lon)) = (e.lat, e.lon) {
                raw.nodes.insert(e.id, (lon, lat));
            }
        }
        ElementKind::Way => {
            let had_geometry = e.geometry.is_some();
            let geometry = geometry(e.geometry);
            raw.ways.push(RawWay {
                id: e.id,
                refs: e.nodes,
                // A geometry with holes in it is dropped, and its ids (if any) must resolve.
                geometry: if had_geometry {
                    Some(geometry.unwrap_or_default())
                } else {
                    None
                },
                tags: e.tags,
            });
        }
        ElementKind::Relation => {
            let members = e
                .members
                .into_iter()
                .filter_map(|m| {
                    let kind = match m.kind.as_str() {
                        "node" => MemberKind::Node,
                        "way" => MemberKind::Way,
                        "relation" => MemberKind::Relation,
                        _ => return None,
                    };
                    let had_geometry = m.geometry.is_some();
                    let geometry = geometry(m.geometry);
                    Some(Member {
                        kind,
                        id: m.id,
                        role: m.role,
                        geometry: if had_geometry {
                            Some(geometry.unwrap_or_default())
                        } else {
                            None
                        },
                    })
                })
                .collect();
            raw.relations.push(RawRelation {
                id: e.id,
                members,
                tags: e.tags,
            });
        }
        ElementKind::Other => {}
    }
}

//! Overpass API JSON: `{"elements": [...]}` with nodes, ways and relations; ways and members may
//! carry inline `geometry` (`out geom;`) instead of, or besides, node ids.

use super::OsmError;
use super::raw::{Member, MemberKind, RawOsm, RawRelation, RawWay, Tags};
use serde::Deserialize;

#[derive(Deserialize)]
struct Document {
    elements: Vec<Element>,
}

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

#[derive(Deserialize)]
struct Element {
    #[serde(rename = "type")]
    kind: String,
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

pub fn read(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    let doc: Document = serde_json::from_slice(bytes).map_err(|e| OsmError::Json(e.to_string()))?;
    let mut raw = RawOsm::default();
    for e in doc.elements {
        match e.kind.as_str() {
            "node" => {
                if let (Some(lat), Some(lon)) = (e.lat, e.lon) {
                    raw.nodes.insert(e.id, (lon, lat));
                }
            }
            "way" => {
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
            "relation" => {
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
            _ => {}
        }
    }
    Ok(raw)
}

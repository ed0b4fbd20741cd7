//! Writing building records back as Overpass JSON (the `out body; >; out skel qt;` layout), so
//! imported data can be stored per data tile exactly like an Overpass response and read back by
//! the same reader.
//!
//! Ways keep their node ids. Multipolygon rings, joined from member ways when read, become one
//! member way each, with a synthetic negative id (OSM ids are positive) and their nodes' ids.

use super::assemble::{BuildingRecord, OsmId, Ring};
use serde_json::{Value, json};
use std::collections::BTreeMap;

/// Node id for a ring point without one (Overpass `out geom` input): a negative id derived from
/// the coordinates, stable for the same point.
fn synthetic_node_id(lon: f64, lat: f64) -> i64 {
    let h = lon.to_bits().rotate_left(17) ^ lat.to_bits();
    -((h >> 2) as i64).max(1)
}

fn ring_nodes(ring: &Ring, nodes: &mut BTreeMap<i64, (f64, f64)>) -> Vec<i64> {
    let mut ids: Vec<i64> = ring
        .nodes
        .iter()
        .map(|n| {
            let id = n.id.unwrap_or_else(|| synthetic_node_id(n.lon, n.lat));
            nodes.insert(id, (n.lon, n.lat));
            id
        })
        .collect();
    // Rings are stored open; OSM ways close by repeating the first node.
    if let Some(&first) = ids.first() {
        ids.push(first);
    }
    ids
}

/// The records as an Overpass JSON document.
pub fn write_overpass_json(records: &[&BuildingRecord]) -> Vec<u8> {
    let mut nodes: BTreeMap<i64, (f64, f64)> = BTreeMap::new();
    let mut ways = Vec::new();
    let mut relations = Vec::new();
    for r in records {
        match r.id {
            OsmId::Way(id) => {
                let refs = r.outers.first().map(|o| ring_nodes(o, &mut nodes));
                ways.push(json!({"type": "way", "id": id, "nodes": refs.unwrap_or_default(), "tags": r.tags}));
            }
            OsmId::Relation(id) => {
                let mut members = Vec::new();
                let rings = r
                    .outers
                    .iter()
                    .map(|ring| ("outer", ring))
                    .chain(r.inners.iter().map(|ring| ("inner", ring)));
                for (k, (role, ring)) in rings.enumerate() {
                    let way_id = -(id.saturating_mul(1000).saturating_add(k as i64 + 1));
                    let refs = ring_nodes(ring, &mut nodes);
                    ways.push(json!({"type": "way", "id": way_id, "nodes": refs}));
                    members.push(json!({"type": "way", "ref": way_id, "role": role}));
                }
                relations.push(
                    json!({"type": "relation", "id": id, "members": members, "tags": r.tags}),
                );
            }
        }
    }
    let mut elements: Vec<Value> = Vec::with_capacity(nodes.len() + ways.len() + relations.len());
    elements.extend(ways);
    elements.extend(relations);
    elements.extend(
        nodes
            .into_iter()
            .map(|(id, (lon, lat))| json!({"type": "node", "id": id, "lat": lat, "lon": lon})),
    );
    let doc = json!({"version": 0.6, "generator": "citymesh import", "elements": elements});
    serde_json::to_vec(&doc).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::{RingNode, Tags, read_buildings};

    fn ring(points: &[(i64, f64, f64)]) -> Ring {
        Ring {
            nodes: points
                .iter()
                .map(|&(id, lon, lat)| RingNode {
                    id: Some(id),
                    lon,
                    lat,
                })
                .collect(),
        }
    }

    #[test]
    fn records_survive_a_round_trip() {
        let tags: Tags = [("building".to_owned(), "yes".to_owned())].into();
        let way = BuildingRecord {
            id: OsmId::Way(5),
            is_part: false,
            outers: vec![ring(&[
                (1, 8.0, 49.0),
                (2, 8.001, 49.0),
                (3, 8.001, 49.001),
            ])],
            inners: vec![],
            tags: tags.clone(),
        };
        let rel = BuildingRecord {
            id: OsmId::Relation(9),
            is_part: false,
            outers: vec![ring(&[
                (10, 8.0, 49.0),
                (11, 8.01, 49.0),
                (12, 8.01, 49.01),
                (13, 8.0, 49.01),
            ])],
            inners: vec![ring(&[
                (20, 8.002, 49.002),
                (21, 8.003, 49.002),
                (22, 8.003, 49.003),
            ])],
            tags: [
                ("building".to_owned(), "yes".to_owned()),
                ("type".to_owned(), "multipolygon".to_owned()),
            ]
            .into(),
        };
        let back = read_buildings(&write_overpass_json(&[&way, &rel])).unwrap();
        assert_eq!(back.skipped, vec![]);
        assert_eq!(back.buildings.len(), 2);
        assert_eq!(back.buildings[0], way);
        assert_eq!(back.buildings[1].outers, rel.outers);
        assert_eq!(back.buildings[1].inners.len(), 1);
        assert_eq!(back.buildings[1].tags, rel.tags);
    }
}

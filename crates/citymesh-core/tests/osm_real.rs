//! The OSM readers on the real files of `../shared/data/osm`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use citymesh_core::osm::{BuildingRecord, OsmBuildings, read_buildings};
use rstest::rstest;
use serde_json::{Value, json};
use std::collections::HashMap;

use common::osm_bytes as bytes;

fn read(name: &str) -> OsmBuildings {
    read_buildings(&bytes(name)).unwrap()
}

/// Counts from the data README: buildings / parts per file; none of these files has a record the
/// reader must skip.
#[rstest]
#[case("karlsruhe-kirchfeld.osm.pbf", 2995, 31)]
#[case("karlsruhe-kirchfeld.overpass.json", 2995, 31)]
#[case("karlsruhe-kit-nord.osm.pbf", 526, 76)]
#[case("tram-junction.osm.pbf", 265, 15)]
#[case("nuremberg-laufamholz.osm", 118, 0)]
#[case("san-francisco.overpass.json.gz", 617, 0)]
fn every_file_gives_its_buildings_and_parts(
    #[case] file: &str,
    #[case] buildings: usize,
    #[case] parts: usize,
) {
    let b = read(file);
    assert_eq!(b.buildings.iter().filter(|b| !b.is_part).count(), buildings);
    assert_eq!(b.buildings.iter().filter(|b| b.is_part).count(), parts);
    assert_eq!(b.skipped, vec![]);
}

/// Asserts two readings hold the same buildings: ids, tags, node ids, and coordinates to 1e-9 deg
/// (PBF stores 100-nanodegree integers, JSON decimals).
fn assert_same_buildings(a: &[BuildingRecord], b: &[BuildingRecord], compare_ids: bool) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert_eq!((x.id, x.is_part, &x.tags), (y.id, y.is_part, &y.tags));
        for (rx, ry) in x
            .outers
            .iter()
            .chain(&x.inners)
            .zip(y.outers.iter().chain(&y.inners))
        {
            assert_eq!(rx.nodes.len(), ry.nodes.len(), "{}", x.id);
            for (p, q) in rx.nodes.iter().zip(&ry.nodes) {
                if compare_ids {
                    assert_eq!(p.id, q.id);
                }
                assert!(
                    (p.lon - q.lon).abs() < 1e-9 && (p.lat - q.lat).abs() < 1e-9,
                    "{}: {p:?} vs {q:?}",
                    x.id
                );
            }
        }
    }
}

#[test]
fn pbf_and_overpass_json_of_kirchfeld_give_the_same_buildings() {
    let pbf = read("karlsruhe-kirchfeld.osm.pbf");
    let json = read("karlsruhe-kirchfeld.overpass.json");
    assert_same_buildings(&pbf.buildings, &json.buildings, true);
    // Five multipolygon relations, some with courtyards.
    let relations: Vec<_> = json
        .buildings
        .iter()
        .filter(|b| matches!(b.id, citymesh_core::osm::OsmId::Relation(_)))
        .collect();
    assert_eq!(relations.len(), 5);
    assert!(relations.iter().any(|r| !r.inners.is_empty()));
}

/// The real kirchfeld document rewritten in the `out geom;` layout: coordinates inline in ways and
/// relation members, no separate nodes.
fn as_out_geom(doc: &Value) -> Value {
    let elements = doc["elements"].as_array().unwrap();
    let nodes: HashMap<i64, Value> = elements
        .iter()
        .filter(|e| e["type"] == "node")
        .map(|e| {
            (
                e["id"].as_i64().unwrap(),
                json!({"lat": e["lat"], "lon": e["lon"]}),
            )
        })
        .collect();
    let ways: HashMap<i64, &Value> = elements
        .iter()
        .filter(|e| e["type"] == "way")
        .map(|e| (e["id"].as_i64().unwrap(), e))
        .collect();
    let geometry = |way: &Value| -> Value {
        way["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|id| nodes[&id.as_i64().unwrap()].clone())
            .collect()
    };
    let mut out = Vec::new();
    for e in elements {
        if e["type"] == "way" {
            let mut w = e.clone();
            w["geometry"] = geometry(e);
            out.push(w);
        } else if e["type"] == "relation" {
            let mut r = e.clone();
            for m in r["members"].as_array_mut().unwrap() {
                m["geometry"] = geometry(ways[&m["ref"].as_i64().unwrap()]);
            }
            out.push(r);
        }
    }
    json!({"elements": out})
}

#[test]
fn the_out_geom_layout_gives_the_same_buildings() {
    let doc: Value = serde_json::from_slice(&bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
    let geom = read_buildings(&serde_json::to_vec(&as_out_geom(&doc)).unwrap()).unwrap();
    let json = read("karlsruhe-kirchfeld.overpass.json");
    assert_eq!(geom.skipped, vec![]);
    // Way nodes keep their ids (the layout lists them); relation members only have coordinates.
    assert_same_buildings(&geom.buildings, &json.buildings, false);
}

#[test]
fn missing_nodes_and_members_are_skipped_and_the_rest_kept() {
    let mut doc: Value =
        serde_json::from_slice(&bytes("karlsruhe-kirchfeld.overpass.json")).unwrap();
    let elements = doc["elements"].as_array_mut().unwrap();
    // Drop the first node of way 35538135 and the inner member way of relation 1776559.
    let way = elements
        .iter()
        .find(|e| e["type"] == "way" && e["id"] == 35_538_135)
        .unwrap()
        .clone();
    let first_node = way["nodes"][0].as_i64().unwrap();
    elements.retain(|e| {
        let dropped_node = e["type"] == "node" && e["id"] == first_node;
        let dropped_way = e["type"] == "way" && e["id"] == 132_344_585;
        !(dropped_node || dropped_way)
    });
    let b = read_buildings(&serde_json::to_vec(&doc).unwrap()).unwrap();
    let reasons: Vec<String> = b
        .skipped
        .iter()
        .map(|s| format!("{} {}", s.id, s.reason.name()))
        .collect();
    // The dropped node is shared with a neighbour, which loses it too.
    assert!(
        reasons.contains(&"way/35538135 missing_nodes".to_owned()),
        "{reasons:?}"
    );
    // A missing courtyard does not drop the building: it is drawn without it, counted repaired.
    assert!(
        !reasons.iter().any(|r| r.starts_with("relation/1776559")),
        "{reasons:?}"
    );
    let repaired: Vec<String> = b
        .repaired
        .iter()
        .map(|r| format!("{} {}", r.id, r.what))
        .collect();
    assert_eq!(repaired, ["relation/1776559 missing_inner_ring"]);
    let relation = b
        .buildings
        .iter()
        .find(|r| r.id.to_string() == "relation/1776559")
        .unwrap();
    assert!(relation.inners.is_empty() && !relation.outers.is_empty());
    // Skips carry where the data places them: the way keeps its other nodes.
    let way = b
        .skipped
        .iter()
        .find(|s| s.id.to_string() == "way/35538135")
        .unwrap();
    let [w, s, e, n] = way.bounds.unwrap();
    assert!(w < e && s < n && (8.38..8.41).contains(&w) && (49.03..49.07).contains(&s));
    assert_eq!(b.buildings.len() + b.skipped.len(), 2995 + 31);
}

/// Packed, every real file's buildings come back bit for bit, in far fewer bytes than the Overpass
/// JSON the store used to keep (bytes per building, a whole file in one tile: Kirchfeld packs into
/// 54 where its JSON takes 539 to 564, San Francisco 93 against 1,249).
#[rstest]
#[case("karlsruhe-kirchfeld.osm.pbf", 55)]
#[case("karlsruhe-kirchfeld.overpass.json", 55)]
#[case("karlsruhe-kit-nord.osm.pbf", 80)]
#[case("tram-junction.osm.pbf", 95)]
#[case("nuremberg-laufamholz.osm", 55)]
#[case("san-francisco.overpass.json.gz", 95)]
fn every_real_file_packs_and_unpacks_bit_for_bit(
    #[case] file: &str,
    #[case] max_per_building: usize,
) {
    use citymesh_core::osm::{pack, unpack, write_overpass_json};
    let b = read(file);
    let packed = pack(&b);
    let back = unpack(&packed).unwrap();
    let bits = |b: &OsmBuildings| -> Vec<u64> {
        b.buildings
            .iter()
            .flat_map(|r| r.outers.iter().chain(&r.inners))
            .flat_map(|r| &r.nodes)
            .flat_map(|n| [n.lon.to_bits(), n.lat.to_bits()])
            .collect()
    };
    assert_eq!(bits(&back), bits(&b));
    assert_eq!(back, b);
    let json = write_overpass_json(&b.buildings.iter().collect::<Vec<_>>()).len();
    let per = packed.len() / b.buildings.len();
    eprintln!(
        "{file}: {per} B per building packed, {} as JSON",
        json / b.buildings.len()
    );
    assert!(per <= max_per_building, "{per} bytes per building");
}

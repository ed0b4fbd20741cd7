//! Change files applied to stored buildings (`citymesh_core::osm::rebuild`) on the real files:
//! what is stored of a building is enough to build it again exactly, and each kind of edit gives
//! what an import of the edited data gives.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use citymesh_core::osm::{
    ChangeError, OsmBuildings, OsmChange, OsmId, RawWay, pack, read_buildings, read_change,
    rebuild, unpack,
};
use rstest::rstest;

/// A file's buildings as a data tile stores them (packed and read back).
fn stored(name: &str) -> OsmBuildings {
    let b = read_buildings(&common::osm_bytes(name)).unwrap();
    unpack(&pack(&b)).unwrap()
}

/// A change that names every stored node at its own place: every building is touched, and
/// rebuilt from what is stored of it alone, it must come back bit for bit.
#[rstest]
#[case("karlsruhe-kirchfeld.osm.pbf")]
#[case("karlsruhe-kit-nord.osm.pbf")]
#[case("tram-junction.osm.pbf")]
#[case("nuremberg-laufamholz.osm")]
fn every_building_is_rebuilt_exactly_from_what_is_stored(#[case] file: &str) {
    let tile = stored(file);
    let mut change = OsmChange::default();
    for n in tile
        .buildings
        .iter()
        .flat_map(|b| b.outers.iter().chain(&b.inners))
        .flat_map(|r| &r.nodes)
    {
        change.nodes.insert(n.id.unwrap(), Some((n.lon, n.lat)));
    }
    let rebuilt = rebuild(&[&tile], &change).unwrap();
    assert_eq!(rebuilt.removed.len(), tile.buildings.len());
    assert_eq!(rebuilt.now.buildings, tile.buildings);
    assert_eq!(rebuilt.now.member_ways, tile.member_ways);
    assert_eq!(rebuilt.now.repaired, tile.repaired);
    assert_eq!(rebuilt.now.skipped, vec![]);
    let relations = tile
        .buildings
        .iter()
        .filter(|b| matches!(b.id, OsmId::Relation(_)))
        .count();
    assert!(relations > 0 || file != "karlsruhe-kirchfeld.osm.pbf");
}

fn change(body: &str) -> OsmChange {
    read_change(format!("<osmChange version=\"0.6\">{body}</osmChange>").as_bytes()).unwrap()
}

#[test]
fn a_height_edit_touches_that_building_alone() {
    let tile = stored("karlsruhe-kirchfeld.osm.pbf");
    let b = tile
        .buildings
        .iter()
        .find(|b| matches!(b.id, OsmId::Way(_)) && !b.is_part)
        .unwrap();
    let OsmId::Way(id) = b.id else { unreachable!() };
    let refs: String = b.outers[0]
        .nodes
        .iter()
        .chain(std::iter::once(&b.outers[0].nodes[0]))
        .map(|n| format!("<nd ref=\"{}\"/>", n.id.unwrap()))
        .collect();
    let c = change(&format!(
        "<modify><way id=\"{id}\">{refs}<tag k=\"building\" v=\"yes\"/>\
         <tag k=\"height\" v=\"31.5\"/></way></modify>"
    ));
    let rebuilt = rebuild(&[&tile], &c).unwrap();
    assert_eq!(
        rebuilt.removed.iter().copied().collect::<Vec<_>>(),
        vec![b.id]
    );
    assert_eq!(rebuilt.now.buildings.len(), 1);
    let now = &rebuilt.now.buildings[0];
    assert_eq!(now.tags["height"], "31.5");
    assert_eq!(now.outers, b.outers);
}

#[test]
fn unknown_nodes_and_ways_are_refused_by_id() {
    let tile = stored("karlsruhe-kirchfeld.osm.pbf");
    let c = change(
        "<create><way id=\"1\"><nd ref=\"900000000001\"/><nd ref=\"900000000002\"/>\
         <nd ref=\"900000000001\"/><tag k=\"building\" v=\"yes\"/></way></create>",
    );
    let e = rebuild(&[&tile], &c).unwrap_err();
    assert_eq!(
        e,
        ChangeError::UnknownNodes {
            way: 1,
            nodes: vec![900_000_000_001, 900_000_000_002]
        }
    );
    let c = change(
        "<create><relation id=\"5\"><member type=\"way\" ref=\"77\" role=\"outer\"/>\
         <tag k=\"type\" v=\"multipolygon\"/><tag k=\"building\" v=\"yes\"/></relation></create>",
    );
    let e = rebuild(&[&tile], &c).unwrap_err();
    assert_eq!(
        e,
        ChangeError::UnknownWays {
            relation: 5,
            ways: vec![77]
        }
    );
    // A node deleted while a stored building still uses it.
    let used = tile.buildings[0].outers[0].nodes[0].id.unwrap();
    let c = change(&format!("<delete><node id=\"{used}\"/></delete>"));
    assert!(matches!(
        rebuild(&[&tile], &c).unwrap_err(),
        ChangeError::UnknownNodes { .. }
    ));
    let _ = RawWay::default();
}

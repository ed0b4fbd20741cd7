//! Following OpenStreetMap's replication diffs: change files (osmChange) applied to the
//! imported data tiles ([`apply`]), one after another from a feed's `state.txt` and
//! `AAA/BBB/CCC.osc.gz` files ([`feed`]).
//!
//! The imported extent is the set of data tiles an import stored (zoom 14, `source =
//! 'import'`): a change is kept only in those tiles, so a building added outside them is not
//! stored, and nothing fetched from Overpass is touched (it is refreshed by its TTL).

pub mod apply;
pub mod feed;

use super::store::ElementKind;
use citymesh_core::osm::{OsmBuildings, OsmId};

/// The elements the buildings of `osm` are made from: for the index that finds them again.
pub fn elements_of(osm: &OsmBuildings) -> Vec<(ElementKind, i64)> {
    let mut out = Vec::new();
    for b in &osm.buildings {
        out.push(match b.id {
            OsmId::Way(id) => (ElementKind::Way, id),
            OsmId::Relation(id) => (ElementKind::Relation, id),
        });
        let nodes = b.outers.iter().chain(&b.inners).flat_map(|r| &r.nodes);
        out.extend(nodes.filter_map(|n| Some((ElementKind::Node, n.id?))));
    }
    for m in &osm.member_ways {
        out.extend(m.ways.iter().map(|&w| (ElementKind::Way, w)));
        out.extend(m.refs.iter().flatten().map(|&n| (ElementKind::Node, n)));
    }
    out
}

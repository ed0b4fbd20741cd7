//! OSM PBF through the pure-Rust `osmpbf` crate, reading from memory.

use super::OsmError;
use super::raw::{Member, MemberKind, RawOsm, RawRelation, RawWay};
use osmpbf::{Element, ElementReader, RelMemberType};

/// A PBF relation's members (node, way and relation members, with their roles).
pub fn relation_members(r: &osmpbf::Relation<'_>) -> Vec<Member> {
    r.members()
        .map(|m| Member {
            kind: match m.member_type {
                RelMemberType::Node => MemberKind::Node,
                RelMemberType::Way => MemberKind::Way,
                RelMemberType::Relation => MemberKind::Relation,
            },
            id: m.member_id,
            role: m.role().unwrap_or_default().to_owned(),
            geometry: None,
        })
        .collect()
}

pub fn read(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    let reader = ElementReader::new(std::io::Cursor::new(bytes));
    let mut raw = RawOsm::default();
    let tags =
        |iter: osmpbf::TagIter<'_>| iter.map(|(k, v)| (k.to_owned(), v.to_owned())).collect();
    reader
        .for_each(|element| match element {
            Element::Node(n) => {
                raw.nodes.insert(n.id(), (n.lon(), n.lat()));
            }
            Element::DenseNode(n) => {
                raw.nodes.insert(n.id(), (n.lon(), n.lat()));
            }
            Element::Way(w) => raw.ways.push(RawWay {
                id: w.id(),
                refs: w.refs().collect(),
                geometry: None,
                tags: tags(w.tags()),
            }),
            Element::Relation(r) => {
                raw.relations.push(RawRelation {
                    id: r.id(),
                    members: relation_members(&r),
                    tags: tags(r.tags()),
                });
            }
        })
        .map_err(|e| OsmError::Pbf(e.to_string()))?;
    Ok(raw)
}

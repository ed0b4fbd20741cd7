//! A change file applied to stored building records: the buildings it touches are found in the
//! data tiles that hold them, rebuilt from what is stored of them (every ring node keeps its
//! OSM id; a multipolygon keeps its member ways' roles and node ids) with the change laid over
//! it, and assembled again by the same rules as an import ([`assemble`]). So a building edited
//! by a diff is stored exactly as an import of the edited data would store it.
//!
//! What a building is made of and may be touched by: its way (or relation and member ways),
//! and their nodes. A change that draws a building from a node or way that neither the change
//! nor the stored buildings hold is refused ([`ChangeError::UnknownNodes`],
//! [`ChangeError::UnknownWays`]): the store keeps only the elements of buildings.

use super::assemble::{BuildingRecord, MemberWays, OsmBuildings, OsmId, assemble};
use super::change::OsmChange;
use super::is_building_multipolygon;
use super::raw::{Member, MemberKind, RawOsm, RawRelation, RawWay};
use crate::building::cluster::record_bounds;
use foldhash::{HashMap, HashSet};
use std::collections::BTreeSet;

/// Why a change cannot be applied (nothing of it is).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ChangeError {
    #[error(
        "way/{way} refers to nodes that neither the change nor the stored buildings hold: {}",
        list(nodes)
    )]
    UnknownNodes { way: i64, nodes: Vec<i64> },
    #[error(
        "relation/{relation} refers to ways that neither the change nor the stored buildings \
         hold: {}",
        list(ways)
    )]
    UnknownWays { relation: i64, ways: Vec<i64> },
    #[error(
        "{id} was stored before its member ways' nodes were kept (data tile version 2): \
         import the data again to follow changes"
    )]
    Incomplete { id: OsmId },
}

fn list(ids: &[i64]) -> String {
    let shown: Vec<String> = ids.iter().take(10).map(i64::to_string).collect();
    let more = ids.len().saturating_sub(10);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// The elements to look up in the store before a change is applied: every element it names,
/// and what its ways and relations refer to (a new building may share nodes with a stored one).
#[derive(Debug, Default, PartialEq)]
pub struct Lookups {
    pub nodes: BTreeSet<i64>,
    pub ways: BTreeSet<i64>,
    pub relations: BTreeSet<i64>,
}

impl Lookups {
    pub fn of(change: &OsmChange) -> Self {
        let mut l = Lookups::default();
        l.nodes.extend(change.nodes.keys());
        for (id, way) in &change.ways {
            l.ways.insert(*id);
            l.nodes.extend(way.iter().flat_map(|w| &w.refs));
        }
        for (id, rel) in &change.relations {
            l.relations.insert(*id);
            let ways = rel.iter().flat_map(|r| &r.members);
            l.ways
                .extend(ways.filter(|m| m.kind == MemberKind::Way).map(|m| m.id));
        }
        l
    }
}

/// The part of a stored data tile that [`rebuild`] needs for `change`: the buildings it may
/// touch, and those holding a node or member way the change refers to (for their
/// coordinates). Taken tile by tile, so a change over many tiles never holds them all.
pub fn touched_part(tile: &OsmBuildings, change: &OsmChange, lookups: &Lookups) -> OsmBuildings {
    let mut out = OsmBuildings::default();
    for r in &tile.buildings {
        let named = match r.id {
            OsmId::Way(w) => lookups.ways.contains(&w),
            OsmId::Relation(rel) => {
                change.relations.contains_key(&rel)
                    || tile
                        .member_ways
                        .iter()
                        .find(|m| m.relation == rel)
                        .is_some_and(|m| {
                            m.ways.iter().any(|w| lookups.ways.contains(w))
                                || m.refs.iter().flatten().any(|n| lookups.nodes.contains(n))
                        })
            }
        };
        let nodes = r
            .outers
            .iter()
            .chain(&r.inners)
            .flat_map(|ring| &ring.nodes);
        if named
            || nodes
                .filter_map(|n| n.id)
                .any(|n| lookups.nodes.contains(&n))
        {
            out.buildings.push(r.clone());
            if let OsmId::Relation(rel) = r.id
                && let Some(m) = tile.member_ways.iter().find(|m| m.relation == rel)
            {
                out.member_ways.push(m.clone());
            }
        }
    }
    out
}

/// What a change makes of the buildings it touches.
#[derive(Debug, Default)]
pub struct Rebuilt {
    /// Every stored building the change touched: removed from each data tile that holds it
    /// before what it is now is added.
    pub removed: BTreeSet<OsmId>,
    /// Where each removed building was (`[west, south, east, north]`).
    pub old_bounds: Vec<[f64; 4]>,
    /// The touched and the new buildings as they are now (and the ones that cannot be built,
    /// skipped with a reason as an import skips them).
    pub now: OsmBuildings,
}

impl Rebuilt {
    /// The ids a data tile must forget before the new records go in.
    pub fn replaced(&self) -> HashSet<OsmId> {
        let mut ids: HashSet<OsmId> = self.removed.iter().copied().collect();
        ids.extend(self.now.buildings.iter().map(|b| b.id));
        ids.extend(self.now.skipped.iter().map(|s| s.id));
        ids
    }
}

/// The stored buildings of the data tiles looked up, each once.
struct Held<'a> {
    records: HashMap<OsmId, &'a BuildingRecord>,
    members: HashMap<i64, &'a MemberWays>,
    /// Node id -> coordinates, from every ring.
    nodes: HashMap<i64, (f64, f64)>,
    /// Way id -> node ids, from every multipolygon's member ways.
    member_refs: HashMap<i64, &'a [i64]>,
}

impl<'a> Held<'a> {
    fn of(tiles: &[&'a OsmBuildings]) -> Self {
        let mut h = Held {
            records: HashMap::default(),
            members: HashMap::default(),
            nodes: HashMap::default(),
            member_refs: HashMap::default(),
        };
        for t in tiles {
            for r in &t.buildings {
                h.records.entry(r.id).or_insert(r);
                for n in r
                    .outers
                    .iter()
                    .chain(&r.inners)
                    .flat_map(|ring| &ring.nodes)
                {
                    if let Some(id) = n.id {
                        h.nodes.insert(id, (n.lon, n.lat));
                    }
                }
            }
            for m in &t.member_ways {
                h.members.entry(m.relation).or_insert(m);
                if m.is_complete() {
                    for (way, refs) in m.ways.iter().zip(&m.refs) {
                        if !refs.is_empty() {
                            h.member_refs.entry(*way).or_insert(refs.as_slice());
                        }
                    }
                }
            }
        }
        h
    }

    /// A stored building way as raw OSM: its ring closed again, its tags.
    fn way(id: i64, r: &BuildingRecord) -> Result<RawWay, ChangeError> {
        let ring = r
            .outers
            .first()
            .map_or(&[][..], |ring| ring.nodes.as_slice());
        let mut refs = ring
            .iter()
            .map(|n| n.id)
            .collect::<Option<Vec<i64>>>()
            .ok_or(ChangeError::Incomplete { id: r.id })?;
        if let Some(&first) = refs.first() {
            refs.push(first);
        }
        Ok(RawWay {
            id,
            refs,
            geometry: None,
            tags: r.tags.clone(),
        })
    }

    /// A stored multipolygon as raw OSM: its members with their roles, its tags.
    fn relation(&self, r: &BuildingRecord, id: i64) -> Result<RawRelation, ChangeError> {
        let m = self
            .members
            .get(&id)
            .filter(|m| m.is_complete())
            .ok_or(ChangeError::Incomplete { id: r.id })?;
        Ok(RawRelation {
            id,
            members: m
                .ways
                .iter()
                .zip(&m.inner)
                .map(|(&way, &inner)| Member {
                    kind: MemberKind::Way,
                    id: way,
                    role: if inner { "inner" } else { "outer" }.to_owned(),
                    geometry: None,
                })
                .collect(),
            tags: r.tags.clone(),
        })
    }
}

/// Rebuilds the buildings `change` touches among `tiles` (the data tiles the store answered
/// for [`Lookups::of`]), and builds the ones it adds.
pub fn rebuild(tiles: &[&OsmBuildings], change: &OsmChange) -> Result<Rebuilt, ChangeError> {
    let held = Held::of(tiles);
    let changed_node = |id: &Option<i64>| id.is_some_and(|id| change.nodes.contains_key(&id));
    let mut touched: BTreeSet<OsmId> = BTreeSet::new();
    for (id, r) in &held.records {
        let nodes = r
            .outers
            .iter()
            .chain(&r.inners)
            .flat_map(|ring| &ring.nodes);
        let by_element = match id {
            OsmId::Way(w) => change.ways.contains_key(w),
            OsmId::Relation(rel) => {
                change.relations.contains_key(rel)
                    || held.members.get(rel).is_some_and(|m| {
                        m.ways.iter().any(|w| change.ways.contains_key(w))
                            || m.refs
                                .iter()
                                .flatten()
                                .any(|n| change.nodes.contains_key(n))
                    })
            }
        };
        if by_element || nodes.map(|n| &n.id).any(changed_node) {
            touched.insert(*id);
        }
    }
    // A stored way that a changed multipolygon now draws as its outline stops being a building
    // of its own: it is rebuilt with the relation.
    for rel in change.relations.values().flatten() {
        for m in rel.members.iter().filter(|m| m.kind == MemberKind::Way) {
            if held.records.contains_key(&OsmId::Way(m.id)) {
                touched.insert(OsmId::Way(m.id));
            }
        }
    }

    let mut raw = RawOsm {
        nodes: held.nodes.clone(),
        ..RawOsm::default()
    };
    for (id, at) in &change.nodes {
        match at {
            Some(at) => raw.nodes.insert(*id, *at),
            None => raw.nodes.remove(id),
        };
    }
    let mut ways: HashMap<i64, RawWay> = HashMap::default();
    let mut relations: HashMap<i64, RawRelation> = HashMap::default();
    for (id, r) in touched
        .iter()
        .filter_map(|id| Some((id, *held.records.get(id)?)))
    {
        match *id {
            OsmId::Way(w) => {
                ways.insert(w, Held::way(w, r)?);
            }
            OsmId::Relation(rel) => {
                relations.insert(rel, held.relation(r, rel)?);
            }
        }
    }
    // The change laid over the stored elements.
    for (id, rel) in &change.relations {
        match rel {
            Some(rel) if is_building_multipolygon(&rel.tags) => {
                relations.insert(*id, rel.clone());
            }
            _ => {
                relations.remove(id);
            }
        }
    }
    for (id, way) in &change.ways {
        match way {
            Some(w) => {
                let building = super::building_kind(&w.tags).is_some();
                if building || ways.contains_key(id) {
                    ways.insert(*id, w.clone());
                }
            }
            None => {
                ways.remove(id);
            }
        }
    }
    // Every member way of a multipolygon kept: from the change, else as stored.
    for rel in relations.values() {
        let mut unknown = Vec::new();
        for m in rel.members.iter().filter(|m| m.kind == MemberKind::Way) {
            if ways.contains_key(&m.id) {
                continue;
            }
            match change.ways.get(&m.id) {
                Some(Some(w)) => {
                    ways.insert(m.id, w.clone());
                }
                Some(None) => unknown.push(m.id),
                None => match (
                    held.member_refs.get(&m.id),
                    held.records.get(&OsmId::Way(m.id)),
                ) {
                    (Some(refs), _) => {
                        ways.insert(
                            m.id,
                            RawWay {
                                id: m.id,
                                refs: refs.to_vec(),
                                ..RawWay::default()
                            },
                        );
                    }
                    (None, Some(r)) => {
                        ways.insert(m.id, Held::way(m.id, r)?);
                    }
                    (None, None) => unknown.push(m.id),
                },
            }
        }
        if !unknown.is_empty() {
            unknown.sort_unstable();
            return Err(ChangeError::UnknownWays {
                relation: rel.id,
                ways: unknown,
            });
        }
    }
    let mut way_list: Vec<RawWay> = ways.into_values().collect();
    way_list.sort_by_key(|w| w.id);
    for w in &way_list {
        let mut missing: Vec<i64> = w
            .refs
            .iter()
            .filter(|n| !raw.nodes.contains_key(n))
            .copied()
            .collect();
        if !missing.is_empty() {
            missing.sort_unstable();
            missing.dedup();
            return Err(ChangeError::UnknownNodes {
                way: w.id,
                nodes: missing,
            });
        }
    }
    raw.ways = way_list;
    raw.relations = relations.into_values().collect();
    raw.relations.sort_by_key(|r| r.id);
    let now = assemble(raw);
    let old_bounds = touched
        .iter()
        .filter_map(|id| held.records.get(id))
        .map(|r| record_bounds(r))
        .collect();
    Ok(Rebuilt {
        removed: touched,
        old_bounds,
        now,
    })
}

/// One data tile with `rebuilt` applied: the replaced buildings (and their skips, repairs and
/// member ways) gone, `add` (the new records this tile holds) and `skipped_here` in, sorted by
/// id as an import sorts them.
pub fn update_tile(
    tile: &mut OsmBuildings,
    rebuilt: &Rebuilt,
    replaced: &HashSet<OsmId>,
    add: &[&BuildingRecord],
    skipped_here: &[super::assemble::Skipped],
) {
    tile.buildings.retain(|b| !replaced.contains(&b.id));
    tile.skipped.retain(|s| !replaced.contains(&s.id));
    tile.repaired.retain(|r| !replaced.contains(&r.id));
    tile.member_ways
        .retain(|m| !replaced.contains(&OsmId::Relation(m.relation)));
    for r in add {
        tile.buildings.push((*r).clone());
        if let Some(rep) = rebuilt.now.repaired.iter().find(|x| x.id == r.id) {
            tile.repaired.push(*rep);
        }
        if let OsmId::Relation(rel) = r.id
            && let Some(m) = rebuilt.now.member_ways.iter().find(|m| m.relation == rel)
        {
            tile.member_ways.push(m.clone());
        }
    }
    tile.skipped.extend_from_slice(skipped_here);
    tile.buildings.sort_by_key(|b| b.id);
    tile.skipped.sort_by_key(|s| s.id);
    tile.repaired.sort_by_key(|r| r.id);
    tile.member_ways.sort_by_key(|m| m.relation);
}

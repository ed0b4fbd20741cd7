//! The elements of an OSM document as the readers produce them, before buildings are assembled.

use foldhash::HashMap;
use std::collections::BTreeMap;

/// OSM tags of one element.
pub type Tags = BTreeMap<String, String>;

/// Nodes, ways and relations of one OSM document.
#[derive(Debug, Clone, Default)]
pub struct RawOsm {
    /// Node id -> (lon, lat).
    pub nodes: HashMap<i64, (f64, f64)>,
    pub ways: Vec<RawWay>,
    pub relations: Vec<RawRelation>,
}

#[derive(Debug, Clone, Default)]
pub struct RawWay {
    pub id: i64,
    /// Node ids; may be empty when the document only gives geometry.
    pub refs: Vec<i64>,
    /// Inline (lon, lat) coordinates (Overpass `out geom`), one per ref when both are present.
    pub geometry: Option<Vec<(f64, f64)>>,
    pub tags: Tags,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MemberKind {
    Node,
    Way,
    Relation,
}

#[derive(Debug, Clone)]
pub struct Member {
    pub kind: MemberKind,
    pub id: i64,
    pub role: String,
    /// Inline (lon, lat) coordinates of a way member (Overpass `out geom`).
    pub geometry: Option<Vec<(f64, f64)>>,
}

#[derive(Debug, Clone, Default)]
pub struct RawRelation {
    pub id: i64,
    pub members: Vec<Member>,
    pub tags: Tags,
}

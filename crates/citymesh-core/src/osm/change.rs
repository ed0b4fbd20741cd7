//! OpenStreetMap change files (osmChange XML, `.osc`: `<osmChange><create>`, `<modify>` and
//! `<delete>` blocks of nodes, ways and relations), as replication feeds publish them. Read
//! strictly: a file that is cut short, is not XML or lacks an element's id or a node's
//! coordinates is refused whole, never applied in part.

use super::OsmError;
use super::raw::{Member, MemberKind, RawRelation, RawWay};
use foldhash::HashMap;
use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

/// What a change does to one element.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Create,
    Modify,
    Delete,
}

/// The final state of every element a change file names (a later mention of an element in the
/// file wins, as the file lists changes in order): `None` is deleted.
#[derive(Debug, Clone, Default)]
pub struct OsmChange {
    pub nodes: HashMap<i64, Option<(f64, f64)>>,
    pub ways: HashMap<i64, Option<RawWay>>,
    pub relations: HashMap<i64, Option<RawRelation>>,
    /// Elements read, with repeats: what the report calls applied.
    pub elements: u64,
}

impl OsmChange {
    /// Whether the change names nothing.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty() && self.ways.is_empty() && self.relations.is_empty()
    }
}

enum Current {
    None,
    Node(i64, Option<(f64, f64)>),
    Way(RawWay),
    Relation(RawRelation),
}

fn bad(reader: &Reader<&[u8]>, what: impl std::fmt::Display) -> OsmError {
    OsmError::Xml(format!(
        "osmChange at byte {}: {what}",
        reader.buffer_position()
    ))
}

fn attr(
    reader: &Reader<&[u8]>,
    e: &BytesStart<'_>,
    key: &[u8],
) -> Result<Option<String>, OsmError> {
    for a in e.attributes() {
        let a = a.map_err(|x| bad(reader, x))?;
        if a.key.as_ref() == key {
            let v = a.unescape_value().map_err(|x| bad(reader, x))?;
            return Ok(Some(v.into_owned()));
        }
    }
    Ok(None)
}

fn required<T: std::str::FromStr>(
    reader: &Reader<&[u8]>,
    e: &BytesStart<'_>,
    key: &str,
) -> Result<T, OsmError> {
    let element = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let v = attr(reader, e, key.as_bytes())?
        .ok_or_else(|| bad(reader, format!("<{element}> has no {key}")))?;
    v.parse().map_err(|_| {
        bad(
            reader,
            format!("<{element}> has {key}=\"{v}\", not a number"),
        )
    })
}

/// Reads an osmChange document (uncompressed).
pub fn read_change(bytes: &[u8]) -> Result<OsmChange, OsmError> {
    let mut reader = Reader::from_reader(bytes);
    let mut out = OsmChange::default();
    let mut action: Option<Action> = None;
    let mut current = Current::None;
    let (mut opened, mut closed) = (false, false);
    loop {
        let event = reader.read_event().map_err(|e| bad(&reader, e))?;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let name = e.name();
                let name = name.as_ref();
                if !opened {
                    if name != b"osmChange" {
                        return Err(bad(&reader, "the document is not an <osmChange>"));
                    }
                    opened = true;
                    closed = empty;
                    continue;
                }
                match name {
                    b"create" | b"modify" | b"delete" if action.is_none() => {
                        action = Some(match name {
                            b"create" => Action::Create,
                            b"modify" => Action::Modify,
                            _ => Action::Delete,
                        });
                        if empty {
                            action = None;
                        }
                    }
                    b"node" | b"way" | b"relation" => {
                        let Some(act) = action else {
                            return Err(bad(
                                &reader,
                                "an element outside <create>, <modify> or <delete>",
                            ));
                        };
                        let id: i64 = required(&reader, e, "id")?;
                        current = match name {
                            b"node" => {
                                let at = if act == Action::Delete {
                                    None
                                } else {
                                    let lat: f64 = required(&reader, e, "lat")?;
                                    let lon: f64 = required(&reader, e, "lon")?;
                                    Some((lon, lat))
                                };
                                Current::Node(id, at)
                            }
                            b"way" => Current::Way(RawWay {
                                id,
                                ..RawWay::default()
                            }),
                            _ => Current::Relation(RawRelation {
                                id,
                                ..RawRelation::default()
                            }),
                        };
                        if empty {
                            finish(
                                &mut out,
                                std::mem::replace(&mut current, Current::None),
                                act,
                            );
                        }
                    }
                    b"nd" => {
                        if let Current::Way(w) = &mut current {
                            w.refs.push(required(&reader, e, "ref")?);
                        }
                    }
                    b"member" => {
                        if let Current::Relation(r) = &mut current {
                            let kind = match attr(&reader, e, b"type")?.as_deref() {
                                Some("node") => MemberKind::Node,
                                Some("way") => MemberKind::Way,
                                Some("relation") => MemberKind::Relation,
                                other => {
                                    return Err(bad(
                                        &reader,
                                        format!("a member of type {other:?}"),
                                    ));
                                }
                            };
                            r.members.push(Member {
                                kind,
                                id: required(&reader, e, "ref")?,
                                role: attr(&reader, e, b"role")?.unwrap_or_default(),
                                geometry: None,
                            });
                        }
                    }
                    b"tag" => {
                        let (k, v) = (attr(&reader, e, b"k")?, attr(&reader, e, b"v")?);
                        if let (Some(k), Some(v)) = (k, v) {
                            match &mut current {
                                Current::Way(w) => {
                                    w.tags.insert(k, v);
                                }
                                Current::Relation(r) => {
                                    r.tags.insert(k, v);
                                }
                                Current::Node(..) | Current::None => {}
                            }
                        }
                    }
                    _ => {}
                }
            }
            Event::End(ref e) => match e.name().as_ref() {
                b"node" | b"way" | b"relation" => {
                    if let Some(act) = action {
                        finish(
                            &mut out,
                            std::mem::replace(&mut current, Current::None),
                            act,
                        );
                    }
                }
                b"create" | b"modify" | b"delete" => action = None,
                b"osmChange" => closed = true,
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
    }
    if !opened {
        return Err(OsmError::Xml("osmChange: no <osmChange> element".into()));
    }
    if !closed {
        return Err(OsmError::Xml(
            "osmChange: the file ends before </osmChange> (cut short?)".into(),
        ));
    }
    Ok(out)
}

fn finish(out: &mut OsmChange, element: Current, action: Action) {
    let keep = action != Action::Delete;
    match element {
        Current::Node(id, at) => {
            out.nodes.insert(id, at.filter(|_| keep));
        }
        Current::Way(w) => {
            out.ways.insert(w.id, keep.then_some(w));
        }
        Current::Relation(r) => {
            out.relations.insert(r.id, keep.then_some(r));
        }
        Current::None => return,
    }
    out.elements += 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    const CHANGE: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<osmChange version="0.6" generator="test">
  <create>
    <node id="-1" version="1" lat="49.01" lon="8.40"/>
    <way id="10" version="1"><nd ref="1"/><nd ref="2"/><tag k="building" v="yes"/></way>
  </create>
  <modify>
    <node id="2" version="2" lat="49.02" lon="8.41"/>
    <relation id="7" version="3">
      <member type="way" ref="10" role="outer"/>
      <tag k="type" v="multipolygon"/>
    </relation>
  </modify>
  <delete>
    <way id="11" version="4"/>
    <node id="2" version="3"/>
  </delete>
</osmChange>"#;

    #[test]
    fn creates_modifies_and_deletes_are_read_the_last_one_winning() {
        let c = read_change(CHANGE.as_bytes()).unwrap();
        assert_eq!(c.elements, 6);
        assert_eq!(c.nodes[&-1], Some((8.40, 49.01)));
        // Modified, then deleted later in the same file.
        assert_eq!(c.nodes[&2], None);
        let w = c.ways[&10].as_ref().unwrap();
        assert_eq!(w.refs, vec![1, 2]);
        assert_eq!(w.tags["building"], "yes");
        assert!(c.ways[&11].is_none());
        let r = c.relations[&7].as_ref().unwrap();
        assert_eq!((r.members[0].id, r.members[0].role.as_str()), (10, "outer"));
    }

    #[test]
    fn a_file_cut_short_or_wrong_is_refused() {
        let cut = &CHANGE[..CHANGE.len() / 2];
        let e = read_change(cut.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("osmChange"), "{e}");
        assert!(read_change(b"<osm></osm>").is_err());
        assert!(read_change(b"").is_err());
        let no_lat = r#"<osmChange><modify><node id="1" lon="8"/></modify></osmChange>"#;
        let e = read_change(no_lat.as_bytes()).unwrap_err().to_string();
        assert!(e.contains("has no lat"), "{e}");
        let bad_id = r#"<osmChange><delete><way id="x"/></delete></osmChange>"#;
        assert!(read_change(bad_id.as_bytes()).is_err());
        let outside = r#"<osmChange><node id="1" lat="1" lon="2"/></osmChange>"#;
        assert!(read_change(outside.as_bytes()).is_err());
    }
}

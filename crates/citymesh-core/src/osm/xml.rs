//! OSM XML (`<osm><node/><way><nd/><tag/></way><relation><member/></relation></osm>`).

use super::OsmError;
use super::raw::{Member, MemberKind, RawOsm, RawRelation, RawWay};
use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

enum Current {
    None,
    Node,
    Way(RawWay),
    Relation(RawRelation),
}

fn attributes(e: &BytesStart<'_>) -> Result<Vec<(Vec<u8>, String)>, OsmError> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|e| OsmError::Xml(e.to_string()))?;
            let value = a
                .unescape_value()
                .map_err(|e| OsmError::Xml(e.to_string()))?
                .into_owned();
            Ok((a.key.as_ref().to_vec(), value))
        })
        .collect()
}

fn get<'a>(attrs: &'a [(Vec<u8>, String)], key: &[u8]) -> Option<&'a str> {
    attrs
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

fn number<T: std::str::FromStr>(attrs: &[(Vec<u8>, String)], key: &[u8]) -> Option<T> {
    get(attrs, key)?.parse().ok()
}

pub fn read(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    let mut reader = Reader::from_reader(bytes);
    let mut raw = RawOsm::default();
    let mut current = Current::None;
    let mut buf = Vec::new();
    let mut seen_root = false;
    loop {
        let event = reader
            .read_event_into(&mut buf)
            .map_err(|e| OsmError::Xml(format!("at byte {}: {e}", reader.buffer_position())))?;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let attrs = attributes(e)?;
                match e.name().as_ref() {
                    b"osm" | b"osmChange" => seen_root = true,
                    b"node" => {
                        if let (Some(id), Some(lat), Some(lon)) = (
                            number::<i64>(&attrs, b"id"),
                            number::<f64>(&attrs, b"lat"),
                            number::<f64>(&attrs, b"lon"),
                        ) {
                            raw.nodes.insert(id, (lon, lat));
                        }
                        current = if empty { Current::None } else { Current::Node };
                    }
                    b"way" => {
                        let way = RawWay {
                            id: number(&attrs, b"id").unwrap_or(0),
                            ..RawWay::default()
                        };
                        if empty {
                            raw.ways.push(way);
                        } else {
                            current = Current::Way(way);
                        }
                    }
                    b"relation" => {
                        let rel = RawRelation {
                            id: number(&attrs, b"id").unwrap_or(0),
                            ..RawRelation::default()
                        };
                        if empty {
                            raw.relations.push(rel);
                        } else {
                            current = Current::Relation(rel);
                        }
                    }
                    b"nd" => {
                        if let (Current::Way(w), Some(r)) =
                            (&mut current, number::<i64>(&attrs, b"ref"))
                        {
                            w.refs.push(r);
                        }
                    }
                    b"member" => {
                        let kind = match get(&attrs, b"type") {
                            Some("node") => Some(MemberKind::Node),
                            Some("way") => Some(MemberKind::Way),
                            Some("relation") => Some(MemberKind::Relation),
                            _ => None,
                        };
                        if let (Current::Relation(r), Some(kind), Some(id)) =
                            (&mut current, kind, number::<i64>(&attrs, b"ref"))
                        {
                            let role = get(&attrs, b"role").unwrap_or_default().to_owned();
                            r.members.push(Member {
                                kind,
                                id,
                                role,
                                geometry: None,
                            });
                        }
                    }
                    b"tag" => {
                        if let (Some(k), Some(v)) = (get(&attrs, b"k"), get(&attrs, b"v")) {
                            match &mut current {
                                Current::Way(w) => {
                                    w.tags.insert(k.to_owned(), v.to_owned());
                                }
                                Current::Relation(r) => {
                                    r.tags.insert(k.to_owned(), v.to_owned());
                                }
                                Current::Node | Current::None => {}
                            }
                        }
                    }
                    _ => {}
                }
            }
            Event::End(ref e) => match e.name().as_ref() {
                b"node" => current = Current::None,
                b"way" | b"relation" => match std::mem::replace(&mut current, Current::None) {
                    Current::Way(w) => raw.ways.push(w),
                    Current::Relation(r) => raw.relations.push(r),
                    Current::Node | Current::None => {}
                },
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
        buf.clear();
    }
    if !seen_root {
        return Err(OsmError::Xml("no <osm> element".into()));
    }
    Ok(raw)
}

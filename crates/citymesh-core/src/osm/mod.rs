//! OpenStreetMap input: Overpass JSON (both the `out body; >; out skel qt;` layout with node ids and
//! the `out geom;` layout with inline coordinates), OSM XML and OSM PBF, all read from bytes into
//! one model of building records ([`OsmBuildings`]).
//!
//! Each reader only turns its format into [`RawOsm`]; [`assemble`] then finds the buildings, joins
//! multipolygon rings and skips (and counts) what real data gets wrong.

mod assemble;
mod change;
mod overpass_json;
mod packed;
mod pbf;
mod raw;
mod update;
mod write;
mod xml;

pub use assemble::{
    BuildingRecord, MAX_BUILDING_EXTENT_M, MAX_TAG_BYTES, MemberWays, OsmBuildings, OsmId,
    Repaired, Ring, RingNode, SkipReason, Skipped, assemble, building_kind,
};

/// Whether a relation's tags make it a building multipolygon, whose member ways
/// [`assemble`] joins into rings.
pub fn is_building_multipolygon(tags: &Tags) -> bool {
    tags.get("type").map(String::as_str) == Some("multipolygon") && building_kind(tags).is_some()
}
pub use change::{Action, OsmChange, read_change};
pub use packed::{PACKED_VERSION, REPAIRS, is_packed, pack, pack_parts, unpack};
pub use pbf::relation_members;
pub use raw::{Member, MemberKind, RawOsm, RawRelation, RawWay, Tags};
pub use update::{ChangeError, Lookups, Rebuilt, rebuild, touched_part, update_tile};
pub use write::write_overpass_json;

/// The OSM formats citymesh reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OsmFormat {
    OverpassJson,
    Xml,
    Pbf,
    /// A data tile as citymesh stores it ([`pack`]).
    Packed,
}

/// Why OSM input could not be read at all (a bad building is skipped instead, see [`SkipReason`]).
#[derive(Debug, thiserror::Error)]
pub enum OsmError {
    #[error("not Overpass JSON: {0}")]
    Json(String),
    #[error("not OSM XML: {0}")]
    Xml(String),
    #[error("not an OSM PBF file: {0}")]
    Pbf(String),
    #[error("{0}")]
    Packed(String),
    #[error("unrecognised OSM data: expected Overpass JSON, OSM XML or OSM PBF")]
    UnknownFormat,
}

impl OsmFormat {
    /// Recognises the format from the first bytes.
    pub fn sniff(bytes: &[u8]) -> Option<Self> {
        let start = bytes
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .map_or(&[][..], |i| &bytes[i..]);
        if is_packed(bytes) {
            return Some(Self::Packed);
        }
        match start.first() {
            Some(b'{') => Some(Self::OverpassJson),
            Some(b'<') => Some(Self::Xml),
            // A PBF file starts with the 4-byte length of its first BlobHeader, then "OSMHeader".
            _ if bytes
                .get(4..bytes.len().min(20))
                .is_some_and(|head| head.windows(9).any(|w| w == b"OSMHeader")) =>
            {
                Some(Self::Pbf)
            }
            _ => None,
        }
    }
}

/// Reads OSM data in any supported format (recognised from its bytes) into building records.
pub fn read_buildings(bytes: &[u8]) -> Result<OsmBuildings, OsmError> {
    if is_packed(bytes) {
        return unpack(bytes);
    }
    Ok(assemble(read_raw(bytes)?))
}

/// Reads OSM data in any supported format into the raw element model.
pub fn read_raw(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    match OsmFormat::sniff(bytes).ok_or(OsmError::UnknownFormat)? {
        OsmFormat::OverpassJson => overpass_json::read(bytes),
        OsmFormat::Xml => xml::read(bytes),
        OsmFormat::Pbf => pbf::read(bytes),
        OsmFormat::Packed => Err(OsmError::Packed(
            "a packed data tile holds building records, not OSM elements".to_owned(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One building way over a square near Karlsruhe whose third node is at `third`, with a
    /// `name` of `name_len` bytes.
    fn square_way(third: (f64, f64), name_len: usize) -> Vec<u8> {
        let name = "n".repeat(name_len);
        format!(
            r#"{{"elements":[{{"type":"node","id":1,"lat":49.01,"lon":8.4}},
            {{"type":"node","id":2,"lat":49.01,"lon":8.4002}},
            {{"type":"node","id":3,"lat":{},"lon":{}}},
            {{"type":"node","id":4,"lat":49.0102,"lon":8.4}},
            {{"type":"way","id":77,"nodes":[1,2,3,4,1],"tags":{{"building":"yes","name":"{name}"}}}}]}}"#,
            third.1, third.0
        )
        .into_bytes()
    }

    #[test]
    fn outlines_no_building_has_are_skipped_and_long_tags_left_out() {
        let fine = read_buildings(&square_way((8.4002, 49.0102), 10)).unwrap();
        assert_eq!(fine.buildings.len(), 1);
        assert!(fine.repaired.is_empty());
        // 1.9 km north: still a building; 2.1 km: not.
        let north = |m: f64| (8.4002, 49.0102 + m / 111_320.0);
        assert_eq!(
            read_buildings(&square_way(north(1_900.0), 1))
                .unwrap()
                .buildings
                .len(),
            1
        );
        let far = read_buildings(&square_way(north(2_100.0), 1)).unwrap();
        assert!(far.buildings.is_empty());
        assert_eq!(
            far.skipped
                .iter()
                .map(|s| (s.id.to_string(), s.reason))
                .collect::<Vec<_>>(),
            vec![("way/77".to_owned(), SkipReason::TooLarge)]
        );
        assert!(far.skipped[0].bounds.is_some());
        for third in [(8.4002, 86.0), (181.0, 49.0102)] {
            let out = read_buildings(&square_way(third, 1)).unwrap();
            assert_eq!(out.skipped[0].reason, SkipReason::OutOfRange, "{third:?}");
        }
        // A tag of 1,024 bytes stays; one byte more and it is left out, reported.
        let kept = read_buildings(&square_way((8.4002, 49.0102), MAX_TAG_BYTES)).unwrap();
        assert_eq!(kept.buildings[0].tags["name"].len(), MAX_TAG_BYTES);
        let long = read_buildings(&square_way((8.4002, 49.0102), MAX_TAG_BYTES + 1)).unwrap();
        assert!(!long.buildings[0].tags.contains_key("name"));
        assert_eq!(long.buildings[0].tags["building"], "yes");
        assert_eq!(
            long.repaired,
            vec![Repaired {
                id: OsmId::Way(77),
                what: "tag_too_long"
            }]
        );
    }

    #[test]
    fn sniff_reads_short_inputs_without_panicking() {
        // A PBF starts with a 4-byte length, then the BlobHeader naming "OSMHeader".
        let mut pbf = vec![0, 0, 0, 14, 0x0a, 0x09];
        pbf.extend_from_slice(b"OSMHeader");
        for len in 0..pbf.len() {
            assert_eq!(OsmFormat::sniff(&pbf[..len]), None, "{len} bytes");
        }
        assert_eq!(OsmFormat::sniff(&pbf), Some(OsmFormat::Pbf));
        // 17 to 19 bytes used to be sliced past their end.
        for len in 17..20 {
            assert_eq!(OsmFormat::sniff(&vec![7u8; len]), None);
        }
        assert_eq!(
            OsmFormat::sniff(b"  {\"elements\":[]}"),
            Some(OsmFormat::OverpassJson)
        );
        assert_eq!(OsmFormat::sniff(b"<osm/>"), Some(OsmFormat::Xml));
    }
}

//! OpenStreetMap input: Overpass JSON (both the `out body; >; out skel qt;` layout with node ids and
//! the `out geom;` layout with inline coordinates), OSM XML and OSM PBF, all read from bytes into
//! one model of building records ([`OsmBuildings`]).
//!
//! Each reader only turns its format into [`RawOsm`]; [`assemble`] then finds the buildings, joins
//! multipolygon rings and skips (and counts) what real data gets wrong.

mod assemble;
mod overpass_json;
mod pbf;
mod raw;
mod write;
mod xml;

pub use assemble::{
    BuildingRecord, OsmBuildings, OsmId, Repaired, Ring, RingNode, SkipReason, Skipped, assemble,
};
pub use raw::{Member, MemberKind, RawOsm, RawRelation, RawWay, Tags};
pub use write::write_overpass_json;

/// The OSM formats citymesh reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OsmFormat {
    OverpassJson,
    Xml,
    Pbf,
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
    Ok(assemble(read_raw(bytes)?))
}

/// Reads OSM data in any supported format into the raw element model.
pub fn read_raw(bytes: &[u8]) -> Result<RawOsm, OsmError> {
    match OsmFormat::sniff(bytes).ok_or(OsmError::UnknownFormat)? {
        OsmFormat::OverpassJson => overpass_json::read(bytes),
        OsmFormat::Xml => xml::read(bytes),
        OsmFormat::Pbf => pbf::read(bytes),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

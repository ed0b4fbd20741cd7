//! Which buildings a box holds: one rule for every place that asks for "the buildings of this
//! box" (the classification route and `citymesh classify`, adaptation examples). A building
//! belongs to the box that holds the centre of its bounding box (every outer ring, borders
//! included), so a building is in a box whole or not at all, and neighbouring boxes that share
//! only a border split buildings between them by one point. Tiles and 3D Tiles use the same
//! point for a cluster of touching buildings ([`super::set::ClusterInfo::representative_point`]),
//! which is the building's own point when it stands alone.

use super::cluster::record_bounds;
use crate::geo::GeoBbox;
use crate::osm::BuildingRecord;

/// Footprints smaller than this (m²) are not classified: sheds, kiosks, mapping slips. The
/// classification route and command count them as `too_small`.
pub const MIN_FOOTPRINT_M2: f64 = 12.0;

/// The centre of a bounding box `[west, south, east, north]`.
pub fn bounds_centre([w, s, e, n]: [f64; 4]) -> (f64, f64) {
    ((w + e) / 2.0, (s + n) / 2.0)
}

/// Whether `bbox` holds `record`: the centre of the record's bounding box lies in it (borders
/// included). A record without outline points is in no box.
pub fn holds(bbox: &GeoBbox, record: &BuildingRecord) -> bool {
    let bounds = record_bounds(record);
    if !bounds.iter().all(|v| v.is_finite()) {
        return false;
    }
    let (lon, lat) = bounds_centre(bounds);
    bbox.contains(lon, lat)
}

/// A lon/lat ring's area in m²: the shoelace formula on an equirectangular projection at the
/// latitude of its first point (exact enough for a building: under 0.1 % across 1 km).
pub fn footprint_area_m2(ring: &[[f64; 2]]) -> f64 {
    let Some(first) = ring.first() else {
        return 0.0;
    };
    let m_per_deg = 111_320.0;
    let kx = m_per_deg * first[1].to_radians().cos();
    let at = |p: [f64; 2]| [(p[0] - first[0]) * kx, (p[1] - first[1]) * m_per_deg];
    let twice: f64 = (0..ring.len())
        .map(|i| {
            let (a, b) = (at(ring[i]), at(ring[(i + 1) % ring.len()]));
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::{OsmId, Ring, RingNode, Tags};

    fn record(ring: &[[f64; 2]]) -> BuildingRecord {
        BuildingRecord {
            id: OsmId::Way(1),
            is_part: false,
            outers: vec![Ring {
                nodes: ring
                    .iter()
                    .map(|&[lon, lat]| RingNode { lon, lat, id: None })
                    .collect(),
            }],
            inners: Vec::new(),
            tags: Tags::default(),
        }
    }

    #[test]
    fn a_building_belongs_to_the_box_holding_its_centre_whole() {
        // 8.000..8.002 x 49.000..49.002: centre (8.001, 49.001).
        let b = record(&[[8.0, 49.0], [8.002, 49.0], [8.002, 49.002], [8.0, 49.002]]);
        let west: GeoBbox = "7.99,48.99,8.0015,49.01".parse().unwrap();
        let east: GeoBbox = "8.0015,48.99,8.01,49.01".parse().unwrap();
        // Its first node and its centre lie in the west box; its east half in the east box.
        assert!(holds(&west, &b));
        assert!(!holds(&east, &b));
        // On the shared border, both boxes hold it (borders included).
        let border: GeoBbox = "8.001,48.99,8.01,49.01".parse().unwrap();
        assert!(holds(&border, &b));
        assert!(!holds(&west, &record(&[])));
    }

    #[test]
    fn footprint_area_of_a_10_by_20_m_rectangle() {
        let (lon, lat) = (8.4f64, 49.0f64);
        let dx = 10.0 / (111_320.0 * lat.to_radians().cos());
        let dy = 20.0 / 111_320.0;
        let ring = [
            [lon, lat],
            [lon + dx, lat],
            [lon + dx, lat + dy],
            [lon, lat + dy],
        ];
        assert!((footprint_area_m2(&ring) - 200.0).abs() < 1e-6);
        assert_eq!(footprint_area_m2(&[]), 0.0);
        assert_eq!(
            bounds_centre([lon, lat, lon + dx, lat + dy]),
            (lon + dx / 2.0, lat + dy / 2.0)
        );
    }
}

//! The pool of footprints training scenes are built from: real OSM outlines or procedural ones,
//! the targets among them, and the ring geometry their layout needs.

use crate::geo::LocalFrame;
use crate::osm::BuildingRecord;
use crate::procedural::{ProceduralParams, generate_city};

/// Footprints to build scenes from: outer rings in metres around one origin, with a coarse grid
/// to find neighbours.
#[derive(Debug, Clone)]
pub struct FootprintPool {
    pub(super) rings: Vec<Vec<[f64; 2]>>,
    pub(super) centres: Vec<[f64; 2]>,
    pub(super) areas: Vec<f64>,
}

/// Footprints smaller or larger than this (m²) are not targets (sheds; halls and blocks).
pub(super) const TARGET_AREA: (f64, f64) = (40.0, 2500.0);

impl FootprintPool {
    /// The footprints of OSM building records: one per record that is not a part and has one
    /// outer ring (its courtyards are ignored).
    pub fn from_records(records: &[BuildingRecord]) -> Self {
        let mut lon = 0.0;
        let mut lat = 0.0;
        let mut n = 0.0;
        for r in records {
            for node in r.outers.iter().flat_map(|o| &o.nodes) {
                lon += node.lon;
                lat += node.lat;
                n += 1.0;
            }
        }
        let frame = if n > 0.0 {
            LocalFrame::new(lon / n, lat / n, 0.0)
        } else {
            LocalFrame::new(0.0, 0.0, 0.0)
        };
        let rings = records
            .iter()
            .filter(|r| !r.is_part && r.outers.len() == 1)
            .map(|r| r.outers[0].local_points(&frame))
            .collect();
        Self::new(rings)
    }

    /// The footprints of a procedural city of this seed (docs/method.md section 10), every layout.
    pub fn procedural(seed: u64) -> Self {
        let params = ProceduralParams {
            seed,
            ..ProceduralParams::default()
        };
        let records = generate_city(&params)
            .map(|c| c.records)
            .unwrap_or_default();
        Self::from_records(&records)
    }

    pub(super) fn new(rings: Vec<Vec<[f64; 2]>>) -> Self {
        let rings: Vec<Vec<[f64; 2]>> = rings
            .into_iter()
            .filter(|r| r.len() >= 3 && r.iter().all(|p| p[0].is_finite() && p[1].is_finite()))
            .collect();
        let centres = rings
            .iter()
            .map(|r| {
                let n = r.len() as f64;
                [
                    r.iter().map(|p| p[0]).sum::<f64>() / n,
                    r.iter().map(|p| p[1]).sum::<f64>() / n,
                ]
            })
            .collect();
        let areas = rings.iter().map(|r| ring_area(r).abs()).collect();
        Self {
            rings,
            centres,
            areas,
        }
    }

    /// How many footprints the pool holds.
    pub fn len(&self) -> usize {
        self.rings.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rings.is_empty()
    }

    /// The indices of footprints fit to be a target.
    pub fn targets(&self) -> Vec<usize> {
        (0..self.rings.len())
            .filter(|&i| (TARGET_AREA.0..=TARGET_AREA.1).contains(&self.areas[i]))
            .collect()
    }
}

/// Twice the signed area (shoelace), halved.
pub(super) fn ring_area(ring: &[[f64; 2]]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// Whether two footprints overlap (one has a vertex inside the other): OSM has a few duplicate
/// outlines and shared building/part outlines that would bury the target.
pub(super) fn overlaps(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
    use crate::building::footprint::inside;
    let shrink = |ring: &[[f64; 2]], p: [f64; 2]| {
        let n = ring.len() as f64;
        let c = [
            ring.iter().map(|q| q[0]).sum::<f64>() / n,
            ring.iter().map(|q| q[1]).sum::<f64>() / n,
        ];
        [c[0] + 0.9 * (p[0] - c[0]), c[1] + 0.9 * (p[1] - c[1])]
    };
    a.iter().any(|&p| inside(b, shrink(a, p))) || b.iter().any(|&p| inside(a, shrink(b, p)))
}

//! Outlines drawn over each other: two buildings (not parts) of a cluster whose footprints
//! overlap, as happens in OpenStreetMap where a building was drawn again over an older one
//! sharing its nodes. Drawn both whole, their walls would coincide where the outlines run
//! together, and every renderer flickers there. The rule: the smaller is drawn whole, and cut
//! out of the larger (as a part is cut out of its outline); the larger is reported as repaired
//! (`overlap_cut_out`). Of two the same size, the later in the cluster is the smaller.

use super::footprint::Footprint;
use geo::{Area, BooleanOps, Coord, LineString, MultiPolygon, Polygon};

/// Outlines overlapping by less than this (m²) only touch.
pub const MIN_OVERLAP: f64 = 0.05;

/// For each record of a cluster (its footprints, and whether it is a part): the records drawn
/// over it and smaller, to cut out of it. Parts are left alone (they are cut out of their
/// outlines already).
pub fn cut_by_smaller(records: &[(&[Footprint], bool)]) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); records.len()];
    // Outlines by the west edge of their bounds, swept east: only those whose bounds overlap
    // are compared.
    let bounds: Vec<Option<[f64; 4]>> = records
        .iter()
        .map(|(f, is_part)| if *is_part { None } else { bounds_of(f) })
        .collect();
    let mut order: Vec<usize> = (0..records.len())
        .filter(|&i| bounds[i].is_some())
        .collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (bounds[a].unwrap_or_default(), bounds[b].unwrap_or_default());
        x[0].total_cmp(&y[0])
    });
    let polygons: Vec<Option<MultiPolygon<f64>>> = vec![None; records.len()];
    let mut polygons = polygons;
    for (k, &i) in order.iter().enumerate() {
        let bi = bounds[i].unwrap_or_default();
        for &j in &order[k + 1..] {
            let bj = bounds[j].unwrap_or_default();
            if bj[0] >= bi[2] {
                break;
            }
            if bj[1] >= bi[3] || bi[1] >= bj[3] {
                continue;
            }
            let a = polygons[i]
                .get_or_insert_with(|| to_multipolygon(records[i].0))
                .clone();
            let b = polygons[j].get_or_insert_with(|| to_multipolygon(records[j].0));
            if a.intersection(b).unsigned_area() < MIN_OVERLAP {
                continue;
            }
            let (ai, aj) = (area(records[i].0), area(records[j].0));
            // The smaller is cut out of the larger; of equal ones the later.
            let (larger, smaller) = if ai > aj || (ai == aj && i < j) {
                (i, j)
            } else {
                (j, i)
            };
            out[larger].push(smaller);
        }
    }
    for cuts in &mut out {
        cuts.sort_unstable();
    }
    out
}

fn area(footprints: &[Footprint]) -> f64 {
    footprints.iter().map(Footprint::area).sum()
}

fn bounds_of(footprints: &[Footprint]) -> Option<[f64; 4]> {
    let mut points = footprints.iter().flat_map(|f| &f.outer.points);
    let first = points.next()?;
    Some(
        points.fold([first[0], first[1], first[0], first[1]], |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        }),
    )
}

fn to_multipolygon(footprints: &[Footprint]) -> MultiPolygon<f64> {
    let line = |r: &super::footprint::FootprintRing| {
        LineString::new(
            r.points
                .iter()
                .map(|p| Coord { x: p[0], y: p[1] })
                .collect(),
        )
    };
    footprints
        .iter()
        .map(|f| {
            MultiPolygon::new(vec![Polygon::new(
                line(&f.outer),
                f.holes.iter().map(line).collect(),
            )])
        })
        .fold(MultiPolygon::new(vec![]), |acc, p| acc.union(&p))
}

//! What a building's neighbours say: the roof shapes tagged nearby, how dense the buildings
//! stand, how large and how aligned the nearest ones are. Streets of one kind of house share
//! one kind of roof.

use super::features::Outline;
use std::collections::HashMap;

/// Tagged neighbours whose shapes are counted: the nearest this many...
pub const TAGGED_NEIGHBOURS: usize = 8;
/// ...within this many metres (centre to centre).
pub const TAGGED_RADIUS_M: f64 = 150.0;
/// Buildings within this many metres count toward the density.
const DENSITY_RADIUS_M: f64 = 50.0;
/// The nearest buildings (tagged or not) within this many metres give the size and alignment.
const NEAR_RADIUS_M: f64 = 100.0;
const NEAR_COUNT: usize = 8;

/// The names of the neighbour columns, in order.
pub fn neighbour_feature_names() -> Vec<String> {
    [
        "tagged_near_flat_share",
        "tagged_near_gabled_share",
        "tagged_near_hipped_share",
        "tagged_near_count",
        "nearest_tagged_distance_m",
        "nearest_tagged_class",
        "buildings_within_50m",
        "log_near_median_area_ratio",
        "nearest_building_axis_difference",
    ]
    .iter()
    .map(|s| (*s).to_owned())
    .collect()
}

/// The outlines of an area, indexed by a grid over their centres.
pub struct Neighbourhood<'a> {
    outlines: &'a [Outline],
    grid: HashMap<(i64, i64), Vec<u32>>,
}

const CELL_M: f64 = 50.0;

fn cell_of(p: [f64; 2]) -> (i64, i64) {
    (
        (p[0] / CELL_M).floor() as i64,
        (p[1] / CELL_M).floor() as i64,
    )
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Keeps the `k` smallest `(distance, index)` pairs seen, in order.
fn keep_nearest(best: &mut Vec<(f64, u32)>, k: usize, d: f64, i: u32) {
    if best.len() == k && best.last().is_some_and(|&(bd, bi)| (d, i) >= (bd, bi)) {
        return;
    }
    let at = best.partition_point(|&(bd, bi)| (bd, bi) < (d, i));
    best.insert(at, (d, i));
    best.truncate(k);
}

impl<'a> Neighbourhood<'a> {
    pub fn new(outlines: &'a [Outline]) -> Self {
        let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (i, o) in outlines.iter().enumerate() {
            grid.entry(cell_of(o.centre)).or_default().push(i as u32);
        }
        Self { outlines, grid }
    }

    /// Calls `visit(index, distance)` for every other outline within `radius` of outline `of`.
    fn around(&self, of: usize, radius: f64, mut visit: impl FnMut(u32, f64)) {
        let c = self.outlines[of].centre;
        let (cx, cy) = cell_of(c);
        let reach = (radius / CELL_M).ceil() as i64;
        for gx in cx - reach..=cx + reach {
            for gy in cy - reach..=cy + reach {
                for &j in self.grid.get(&(gx, gy)).map_or(&[][..], Vec::as_slice) {
                    if j as usize == of {
                        continue;
                    }
                    let d = distance(c, self.outlines[j as usize].centre);
                    if d <= radius {
                        visit(j, d);
                    }
                }
            }
        }
    }

    /// The neighbour columns of outline `of`, where `labels[j]` is the tagged class of outline
    /// `j` (`None` untagged). Its own label is never read.
    pub fn features(&self, of: usize, labels: &[Option<usize>]) -> Vec<f32> {
        let mut tagged: Vec<(f64, u32)> = Vec::with_capacity(TAGGED_NEIGHBOURS + 1);
        self.around(of, TAGGED_RADIUS_M, |j, d| {
            if labels[j as usize].is_some() {
                keep_nearest(&mut tagged, TAGGED_NEIGHBOURS, d, j);
            }
        });
        let mut shares = [f32::NAN; 3];
        if !tagged.is_empty() {
            shares = [0.0; 3];
            for &(_, j) in &tagged {
                if let Some(c) = labels[j as usize].filter(|&c| c < 3) {
                    shares[c] += 1.0 / tagged.len() as f32;
                }
            }
        }
        let nearest_tagged = tagged.first();
        let mut dense = 0usize;
        let mut near: Vec<(f64, u32)> = Vec::with_capacity(NEAR_COUNT + 1);
        self.around(of, NEAR_RADIUS_M, |j, d| {
            if d <= DENSITY_RADIUS_M {
                dense += 1;
            }
            keep_nearest(&mut near, NEAR_COUNT, d, j);
        });
        let own = &self.outlines[of];
        let (area_ratio, axis_difference) = if near.is_empty() {
            (f32::NAN, f32::NAN)
        } else {
            let mut areas: Vec<f64> = near
                .iter()
                .map(|&(_, j)| self.outlines[j as usize].area)
                .collect();
            areas.sort_by(f64::total_cmp);
            let median = areas[areas.len() / 2];
            let other = self.outlines[near[0].1 as usize].axis;
            let turn = (own.axis - other).rem_euclid(std::f64::consts::FRAC_PI_2);
            (
                (median / own.area.max(1.0)).max(1e-6).ln() as f32,
                turn.min(std::f64::consts::FRAC_PI_2 - turn) as f32,
            )
        };
        vec![
            shares[0],
            shares[1],
            shares[2],
            tagged.len() as f32,
            nearest_tagged.map_or(f32::NAN, |&(d, _)| d as f32),
            nearest_tagged
                .and_then(|&(_, j)| labels[j as usize])
                .map_or(f32::NAN, |c| c as f32),
            dense as f32,
            area_ratio,
            axis_difference,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outline(x: f64, y: f64, area: f64) -> Outline {
        Outline {
            centre: [x, y],
            area,
            elongation: 1.0,
            fill: 1.0,
            axis: 0.0,
        }
    }

    #[test]
    fn counts_the_nearest_tagged_shapes_and_never_its_own() {
        // A row of buildings 20 m apart; 0 is flat-tagged, 1..=4 gabled, 5 untagged, 6 far away.
        let mut outlines: Vec<Outline> = (0..6)
            .map(|i| outline(20.0 * i as f64, 0.0, 100.0))
            .collect();
        outlines.push(outline(1000.0, 0.0, 100.0));
        let labels = [Some(0), Some(1), Some(1), Some(1), Some(1), None, Some(2)];
        let n = Neighbourhood::new(&outlines);
        let f = n.features(0, &labels);
        assert_eq!(&f[..4], &[0.0, 1.0, 0.0, 4.0]);
        assert_eq!((f[4], f[5]), (20.0, 1.0));
        assert_eq!(f[6], 2.0, "buildings 1 and 2 are within 50 m");
        assert_eq!(f[7], 0.0, "the same areas");
        let far = n.features(6, &labels);
        assert!(far[0].is_nan() && far[4].is_nan() && far[7].is_nan());
        assert_eq!((far[3], far[6]), (0.0, 0.0));
    }

    #[test]
    fn keeps_the_k_nearest_in_order() {
        let mut best = Vec::new();
        for (d, i) in [(5.0, 1), (1.0, 2), (3.0, 3), (2.0, 4), (9.0, 5)] {
            keep_nearest(&mut best, 3, d, i);
        }
        assert_eq!(best, vec![(1.0, 2), (2.0, 4), (3.0, 3)]);
    }
}

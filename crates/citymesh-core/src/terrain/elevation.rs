//! The elevation of any point: cell corners and Equation 1 (docs/method.md sections 1 and 2).
//!
//! Coordinates here are in sample units: `u = lon * p`, `v = lat * p` with `p` samples per degree,
//! so the cell of sample `(i, j)` spans `[i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]`.

use super::model::{ElevationModel, Sample};

/// A cell corner is the average of the valid cells among the (up to) four around it
/// (docs/method.md section 1). The order of summation is fixed so every caller gets the same bits.
#[inline]
pub fn corner_height(cells: [Option<f64>; 4]) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0u32;
    for h in cells.into_iter().flatten() {
        sum += h;
        n += 1;
    }
    (n > 0).then(|| sum / f64::from(n))
}

/// Equation 1: the height at offset `(du, dv)` from the centre of a cell with centre height `c`
/// and corners `[sw, se, ne, nw]`, each offset in `[-0.5, 0.5]`.
///
/// The cell is cut by its diagonals into four triangles (corner, corner, centre); in the one that
/// holds the point, with base `A`-`B` and apex `C`:
/// `P = A + b * (B - A) + h * (2C - (A + B))`, where `b` is the position along `A`-`B` and `h` the
/// distance from `A`-`B` towards `C`, both in cell units.
#[inline]
pub(crate) fn equation_1(c: f64, corners: [f64; 4], du: f64, dv: f64) -> f64 {
    let t = CellTriangle::holding(du, dv);
    t.height(c, corners[t.a], corners[t.b])
}

/// The triangle of a cell (cut by its diagonals) that holds an offset from the centre: its base
/// corners `A` and `B` as indices into `[sw, se, ne, nw]`, and the point's position `along` the
/// base and `up` from it towards the centre, in cell units.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CellTriangle {
    a: usize,
    b: usize,
    along: f64,
    up: f64,
}

impl CellTriangle {
    #[inline]
    pub(crate) fn holding(du: f64, dv: f64) -> Self {
        let (a, b, along, up) = if du.abs() >= dv.abs() {
            if du >= 0.0 {
                (1, 2, dv + 0.5, 0.5 - du)
            } else {
                (3, 0, 0.5 - dv, du + 0.5)
            }
        } else if dv >= 0.0 {
            (2, 3, 0.5 - du, 0.5 - dv)
        } else {
            (0, 1, du + 0.5, dv + 0.5)
        };
        Self { a, b, along, up }
    }

    /// Equation 1 in this triangle, with centre height `c` and base corner heights `a`, `b`.
    #[inline]
    fn height(self, c: f64, a: f64, b_corner: f64) -> f64 {
        let delta_b = b_corner - a; // Equation 1
        let delta_h = 2.0 * c - (a + b_corner); // Equation 1
        a + self.along * delta_b + self.up * delta_h // Equation 1
    }
}

/// One cell's placement heights (voids filled): the centre and the corners `[sw, se, ne, nw]`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct GroundCell {
    i: i64,
    j: i64,
    centre: f64,
    corners: [f64; 4],
}

/// The cell holding sample-unit coordinate `u`, and the offset from its centre.
#[inline]
pub(crate) fn cell_of(u: f64) -> (i64, f64) {
    let i = (u + 0.5).floor();
    // Keep the offset in [-0.5, 0.5] even where rounding put u exactly on the upper edge.
    (i as i64, (u - i).clamp(-0.5, 0.5))
}

impl ElevationModel {
    /// The ground height at a point by Equation 1, exactly as the ground mesh has it, or `None` over
    /// a void cell (where the mesh has a hole). Missing files count as the 0 m fallback plane.
    pub fn elevation(&self, lon: f64, lat: f64) -> Option<f64> {
        let p = f64::from(self.per_degree());
        self.elevation_with(lon * p, lat * p, |_, _, s| match s {
            Sample::Valid(h) => Some(h),
            Sample::Void => None,
            Sample::Missing => Some(0.0),
        })
    }

    /// The height to place things at: Equation 1 over samples whose voids are filled with the
    /// average of the nearest valid samples around them (docs/method.md section 2, decision). Never
    /// fails: with nothing valid nearby it answers 0 m.
    pub fn ground_height(&self, lon: f64, lat: f64) -> f64 {
        let p = f64::from(self.per_degree());
        self.elevation_with(lon * p, lat * p, |i, j, s| {
            Some(match s {
                Sample::Valid(h) => h,
                Sample::Missing => 0.0,
                Sample::Void => self.filled_sample(i, j),
            })
        })
        .unwrap_or(0.0)
    }

    /// [`ElevationModel::ground_height`], reusing the cell heights of the previous call through
    /// `last` when the point lies in the same cell (a footprint's corners and crossings mostly
    /// do). Gives the same bits as `ground_height`.
    pub(crate) fn ground_height_near(
        &self,
        lon: f64,
        lat: f64,
        last: &mut Option<GroundCell>,
    ) -> f64 {
        let p = f64::from(self.per_degree());
        let (i, du) = cell_of(lon * p);
        let (j, dv) = cell_of(lat * p);
        let cell = match *last {
            Some(c) if c.i == i && c.j == j => c,
            _ => {
                let c = self.ground_cell(i, j);
                *last = Some(c);
                c
            }
        };
        let t = CellTriangle::holding(du, dv);
        t.height(cell.centre, cell.corners[t.a], cell.corners[t.b])
    }

    /// The heights `ground_height` reads in cell `(i, j)`: its centre and its four corners.
    fn ground_cell(&self, i: i64, j: i64) -> GroundCell {
        let window = self.window(i, j);
        let value = |di: i64, dj: i64| match window[(dj + 1) as usize][(di + 1) as usize] {
            Sample::Valid(h) => h,
            Sample::Missing => 0.0,
            Sample::Void => self.filled_sample(i + di, j + dj),
        };
        let corner = |ci: i64, cj: i64| {
            corner_height([
                Some(value(ci, cj)),
                Some(value(ci + 1, cj)),
                Some(value(ci, cj + 1)),
                Some(value(ci + 1, cj + 1)),
            ])
            // Four values: never empty.
            .unwrap_or(0.0)
        };
        GroundCell {
            i,
            j,
            centre: value(0, 0),
            corners: [corner(-1, -1), corner(0, -1), corner(0, 0), corner(-1, 0)],
        }
    }

    fn filled_sample(&self, i: i64, j: i64) -> f64 {
        match self.sample(i, j) {
            Sample::Valid(h) => return h,
            Sample::Missing => return 0.0,
            Sample::Void => {}
        }
        // Grow a square ring around the void until it holds valid samples.
        for r in 1..=64i64 {
            let mut sum = 0.0;
            let mut n = 0u32;
            for dj in -r..=r {
                for di in -r..=r {
                    if di.abs() != r && dj.abs() != r {
                        continue;
                    }
                    if let Sample::Valid(h) = self.sample(i + di, j + dj) {
                        sum += h;
                        n += 1;
                    }
                }
            }
            if n > 0 {
                return sum / f64::from(n);
            }
        }
        0.0
    }

    /// Equation 1 at sample-unit coordinates, each sample read as `value(i, j, sample)` gives it
    /// (`None` = void).
    pub(crate) fn elevation_with(
        &self,
        u: f64,
        v: f64,
        value: impl Fn(i64, i64, Sample) -> Option<f64>,
    ) -> Option<f64> {
        let (i, du) = cell_of(u);
        let (j, dv) = cell_of(v);
        let window = self.window(i, j);
        // The sample at offset (di, dj) from the cell, each in -1..=1.
        let sample =
            |di: i64, dj: i64| value(i + di, j + dj, window[(dj + 1) as usize][(di + 1) as usize]);
        let c = sample(0, 0)?;
        let corner = |ci: i64, cj: i64| {
            corner_height([
                sample(ci, cj),
                sample(ci + 1, cj),
                sample(ci, cj + 1),
                sample(ci + 1, cj + 1),
            ])
        };
        // The centre is valid, so each corner has at least one valid cell. Only the two corners
        // of the triangle holding the point are read.
        let t = CellTriangle::holding(du, dv);
        let corner_at = |k: usize| match k {
            0 => corner(-1, -1),
            1 => corner(0, -1),
            2 => corner(0, 0),
            _ => corner(-1, 0),
        };
        Some(t.height(c, corner_at(t.a)?, corner_at(t.b)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::{HgtTile, VOID};
    use std::sync::Arc;

    #[test]
    fn reusing_a_cell_gives_the_bits_of_ground_height() {
        // A bumpy tile with voids, including a void block that needs the filling rule.
        let mut s: Vec<i16> = (0..1201 * 1201).map(|k| ((k * 37) % 211) as i16).collect();
        for k in [
            600 * 1201 + 600,
            600 * 1201 + 601,
            601 * 1201 + 600,
            5 * 1201 + 7,
        ] {
            s[k] = VOID;
        }
        let m = ElevationModel::new(vec![Arc::new(HgtTile::from_samples(49, 8, s).unwrap())]);
        let mut last = None;
        let mut points = Vec::new();
        // Walks that stay in a cell for a while, cross cells, jump, and reach the file's edges.
        for k in 0..4000 {
            let t = f64::from(k) / 4000.0;
            points.push((8.5 + 0.01 * t, 49.5 + 0.003 * (t * 7.0).sin()));
        }
        points.extend([(8.0, 49.0), (8.999, 49.999), (8.5, 49.5), (8.0058, 49.9962)]);
        for (lon, lat) in points {
            let near = m.ground_height_near(lon, lat, &mut last);
            assert_eq!(
                near.to_bits(),
                m.ground_height(lon, lat).to_bits(),
                "{lon} {lat}"
            );
        }
        // No DEM at all: the 0 m plane.
        let empty = ElevationModel::new(Vec::new());
        assert_eq!(empty.ground_height_near(8.5, 49.5, &mut None), 0.0);
    }

    #[test]
    fn equation_1_meets_every_vertex_of_its_triangles() {
        let corners = [1.0, 2.0, 4.0, 8.0];
        let c = 16.0;
        assert_eq!(equation_1(c, corners, 0.0, 0.0), c);
        assert_eq!(equation_1(c, corners, -0.5, -0.5), 1.0);
        assert_eq!(equation_1(c, corners, 0.5, -0.5), 2.0);
        assert_eq!(equation_1(c, corners, 0.5, 0.5), 4.0);
        assert_eq!(equation_1(c, corners, -0.5, 0.5), 8.0);
        // Midpoint of the south edge: halfway between SW and SE.
        assert_eq!(equation_1(c, corners, 0.0, -0.5), 1.5);
        // Halfway from the east edge's midpoint (3.0) to the centre (16.0).
        assert_eq!(equation_1(c, corners, 0.25, 0.0), 9.5);
    }

    #[test]
    fn corners_average_only_valid_cells() {
        assert_eq!(corner_height([Some(1.0), None, Some(3.0), None]), Some(2.0));
        assert_eq!(corner_height([None; 4]), None);
    }
}

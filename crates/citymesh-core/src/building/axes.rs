//! The alternative coordinate system of a footprint (docs/method.md section 4): two axis directions
//! from grouped wall directions, and the virtual rectangle they span.

use super::length::planar_length;
/// The virtual rectangle of a footprint: `x' = (n.p - x0) / rx`, `y' = (m.p - y0) / ry`, with
/// `rx >= ry`, so the footprint lies in [-1, 1]².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoofAxes {
    pub n: [f64; 2],
    pub m: [f64; 2],
    pub x0: f64,
    pub rx: f64,
    pub y0: f64,
    pub ry: f64,
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// A running group of sides with one direction (step 1 of docs/method.md section 4).
struct DirectionGroup {
    dir: [f64; 2],
    sum: f64,
    min: f64,
    max: f64,
    sides: usize,
    length: f64,
}

impl RoofAxes {
    /// The axes of a ring (`outer`, in metres) by the paper's direction grouping, or the minimum-area
    /// rectangle when fewer than two usable groups exist. `None` for a ring without area.
    pub fn of_ring(outer: &[[f64; 2]]) -> Option<Self> {
        let mut groups: Vec<DirectionGroup> = Vec::new();
        let mut perimeter = 0.0;
        for i in 0..outer.len() {
            let (p, q) = (outer[i], outer[(i + 1) % outer.len()]);
            let d = [q[0] - p[0], q[1] - p[1]];
            let len = planar_length(d[0], d[1]);
            if len < 1e-9 {
                continue;
            }
            perimeter += len;
            let u = [d[0] / len, d[1] / len];
            match groups.iter_mut().find(|g| dot(g.dir, u).abs() > 0.99) {
                Some(g) => {
                    g.sum += if dot(g.dir, u) > 0.0 { len } else { -len };
                    g.min = g.min.min(g.sum);
                    g.max = g.max.max(g.sum);
                    g.sides += 1;
                    g.length += len;
                }
                None => groups.push(DirectionGroup {
                    dir: u,
                    sum: len,
                    min: len,
                    max: len,
                    sides: 1,
                    length: len,
                }),
            }
        }
        // Usable groups have walls on both sides of the footprint; the two axes must be well apart
        // and carry most of the outline, or the rectangle fits badly (circles, triangles).
        groups.retain(|g| g.sides >= 2 && g.max - g.min > 1e-9);
        groups.sort_by(|a, b| (b.max - b.min).total_cmp(&(a.max - a.min)));
        let first = groups.first();
        let second = first.and_then(|f| {
            groups
                .iter()
                .skip(1)
                .find(|g| dot(g.dir, f.dir).abs() < std::f64::consts::FRAC_1_SQRT_2)
        });
        let axes = match (first, second) {
            (Some(f), Some(s)) if f.length + s.length >= 0.5 * perimeter => {
                // The unit normals of the two side directions.
                Self::from_normals(outer, [-f.dir[1], f.dir[0]], [-s.dir[1], s.dir[0]])
            }
            _ => Self::minimum_rectangle(outer),
        };
        axes.filter(|a| a.ry > 1e-6)
    }

    /// The frame with `x'` along a given unit direction (for skillion roofs: `roof:direction`).
    pub fn along(outer: &[[f64; 2]], dir: [f64; 2]) -> Option<Self> {
        // x' stays along `dir` even when the footprint is shorter that way.
        let a = Self::from_normals(outer, dir, [-dir[1], dir[0]])?;
        (a.rx > 1e-6 && a.ry > 1e-6).then_some(a)
    }

    /// The rectangle spanned by the ring's extents along two normals.
    fn from_normals(outer: &[[f64; 2]], n: [f64; 2], m: [f64; 2]) -> Option<Self> {
        let (mut nmin, mut nmax, mut mmin, mut mmax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &p in outer {
            let (pn, pm) = (dot(n, p), dot(m, p));
            nmin = nmin.min(pn);
            nmax = nmax.max(pn);
            mmin = mmin.min(pm);
            mmax = mmax.max(pm);
        }
        if outer.is_empty() {
            return None;
        }
        Some(Self {
            n,
            m,
            x0: (nmax + nmin) / 2.0,
            rx: (nmax - nmin) / 2.0,
            y0: (mmax + mmin) / 2.0,
            ry: (mmax - mmin) / 2.0,
        })
    }

    /// The axes of the minimum-area bounding rectangle (rotating calipers over the hull edges).
    fn minimum_rectangle(outer: &[[f64; 2]]) -> Option<Self> {
        let mut best: Option<(f64, Self)> = None;
        for i in 0..outer.len() {
            let (p, q) = (outer[i], outer[(i + 1) % outer.len()]);
            let d = [q[0] - p[0], q[1] - p[1]];
            let len = planar_length(d[0], d[1]);
            if len < 1e-9 {
                continue;
            }
            let u = [d[0] / len, d[1] / len];
            let a = Self::from_normals(outer, [-u[1], u[0]], u)?;
            let area = a.rx * a.ry;
            if best.as_ref().is_none_or(|(b, _)| area < *b - 1e-12) {
                best = Some((area, a));
            }
        }
        best.map(|(_, a)| a)
    }

    /// With x' made the longer axis (docs/method.md section 4: r_x >= r_y).
    pub fn long_first(mut self) -> Self {
        if self.rx < self.ry {
            std::mem::swap(&mut self.n, &mut self.m);
            std::mem::swap(&mut self.x0, &mut self.y0);
            std::mem::swap(&mut self.rx, &mut self.ry);
        }
        self
    }

    /// Alternative coordinates of a point.
    #[inline]
    pub fn to_alt(&self, p: [f64; 2]) -> [f64; 2] {
        [
            (dot(self.n, p) - self.x0) / self.rx,
            (dot(self.m, p) - self.y0) / self.ry,
        ]
    }

    /// The point with alternative coordinates `(x', y')`: solves n.P = x' rx + x0, m.P = y' ry + y0.
    #[inline]
    pub fn from_alt(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        let (a, b) = (x * self.rx + self.x0, y * self.ry + self.y0);
        let det = self.n[0] * self.m[1] - self.n[1] * self.m[0];
        [
            (a * self.m[1] - b * self.n[1]) / det,
            (self.n[0] * b - self.m[0] * a) / det,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figure_8_style_grouping_picks_the_long_axis() {
        // A 20 x 8 rectangle rotated by 30 degrees, with a collinear extra node on a long side.
        let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
        let rot = |x: f64, y: f64| [x * c - y * s, x * s + y * c];
        let ring = [
            rot(0.0, 0.0),
            rot(12.0, 0.0),
            rot(20.0, 0.0),
            rot(20.0, 8.0),
            rot(0.0, 8.0),
        ];
        let a = RoofAxes::of_ring(&ring).unwrap().long_first();
        assert!(
            (a.rx - 10.0).abs() < 1e-9 && (a.ry - 4.0).abs() < 1e-9,
            "{a:?}"
        );
        // x' runs along the long side.
        assert!((dot(a.n, [c, s]).abs() - 1.0).abs() < 1e-9);
        for p in ring {
            let q = a.from_alt(a.to_alt(p));
            assert!((q[0] - p[0]).abs() < 1e-9 && (q[1] - p[1]).abs() < 1e-9);
        }
        assert_eq!(
            a.to_alt(rot(20.0, 8.0)).map(|v| v.abs().round()),
            [1.0, 1.0]
        );
    }

    #[test]
    fn a_triangle_falls_back_to_the_minimum_rectangle() {
        let a = RoofAxes::of_ring(&[[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]])
            .unwrap()
            .long_first();
        // The smallest box of a right triangle lies along its legs: 10 x 5.
        assert!(
            (a.rx - 5.0).abs() < 1e-9 && (a.ry - 2.5).abs() < 1e-9,
            "{a:?}"
        );
    }
}

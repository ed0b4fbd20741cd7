//! The crop rule: how imagery around one building becomes the classifier's input, the same for
//! training renders and run-time imagery (paper Figure 14, improved).
//!
//! The footprint's minimum rotated rectangle is turned so its long side is horizontal, scaled so
//! the long side fills a fixed share of the crop (the rest is context), and sampled into a square
//! of `size` pixels, with the footprint as an optional mask channel.

use super::image::{Image, linear_to_srgb8};

/// The crop's size and how much of it the footprint fills.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CropRule {
    /// Side of the square crop in pixels.
    pub size: usize,
    /// Share of the crop's width the footprint's long side fills.
    pub fill: f64,
}

impl CropRule {
    /// The rule the committed model was trained with: 96 px, the footprint's long side across
    /// 80 % of the width (the model masks what lies outside the footprint, so a wide margin
    /// would only waste pixels; a narrow one keeps overhangs and shifted imagery in view).
    pub const MODEL: CropRule = CropRule {
        size: 96,
        fill: 0.8,
    };
}

/// Where a crop lies in the world: a square of `size` pixels centred on `centre`, its x axis along
/// `axis`, each pixel `metres_per_pixel` on the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CropFrame {
    pub centre: [f64; 2],
    /// Unit vector of the crop's x axis (the footprint's long side) in world `[east, north]`.
    pub axis: [f64; 2],
    pub metres_per_pixel: f64,
    pub size: usize,
}

/// A crop: 8-bit sRGB pixels and the footprint mask (255 inside), row by row, `size` square.
#[derive(Debug, Clone, PartialEq)]
pub struct Crop {
    pub size: usize,
    pub rgb: Vec<[u8; 3]>,
    /// `None` when the footprint is not known.
    pub mask: Option<Vec<u8>>,
}

/// The value of the mask channel where the footprint is not known (what a grey 128 alpha holds).
pub const UNKNOWN_MASK: f32 = 128.0 / 255.0;

impl Crop {
    /// The model's input: channels R, G, B in [0, 1] (sRGB values / 255) and the mask (1 inside,
    /// 0 outside, [`UNKNOWN_MASK`] everywhere when not known), planar, row by row.
    pub fn tensor(&self) -> Vec<f32> {
        let n = self.size * self.size;
        let mut t = vec![0.0f32; 4 * n];
        for (i, p) in self.rgb.iter().enumerate() {
            for c in 0..3 {
                t[c * n + i] = f32::from(p[c]) / 255.0;
            }
            t[3 * n + i] = match &self.mask {
                Some(m) => f32::from(m[i]) / 255.0,
                None => UNKNOWN_MASK,
            };
        }
        t
    }
}

impl CropFrame {
    /// The crop frame of a footprint (its outer ring, in metres) by `rule`; `None` when the
    /// footprint has no extent or is not finite.
    pub fn of_footprint(outer: &[[f64; 2]], rule: CropRule) -> Option<Self> {
        let rect = min_rotated_rect(outer)?;
        Some(Self {
            centre: rect.centre,
            axis: rect.axis,
            metres_per_pixel: rect.length / (rule.fill * rule.size as f64),
            size: rule.size,
        })
    }

    /// The world point at continuous crop pixel coordinates (centres at `i + 0.5`, y down).
    #[inline]
    pub fn world_at(&self, x: f64, y: f64) -> [f64; 2] {
        let half = self.size as f64 / 2.0;
        let u = (x - half) * self.metres_per_pixel;
        let v = (half - y) * self.metres_per_pixel;
        let [ax, ay] = self.axis;
        [
            self.centre[0] + u * ax - v * ay,
            self.centre[1] + u * ay + v * ax,
        ]
    }

    /// The ground box `[min, max]` the crop covers.
    pub fn bounds(&self) -> [[f64; 2]; 2] {
        let s = self.size as f64;
        let corners = [(0.0, 0.0), (s, 0.0), (0.0, s), (s, s)].map(|(x, y)| self.world_at(x, y));
        let mut b = [[f64::INFINITY; 2], [f64::NEG_INFINITY; 2]];
        for c in corners {
            for k in 0..2 {
                b[0][k] = b[0][k].min(c[k]);
                b[1][k] = b[1][k].max(c[k]);
            }
        }
        b
    }

    /// Samples `image` into the crop; `to_pixel` maps a world point to the image's pixel
    /// coordinates and `source_metres_per_pixel` is the image's ground resolution. Each crop pixel
    /// averages up to 4x4 samples where the image is finer than the crop.
    pub fn sample(
        &self,
        image: &Image,
        to_pixel: impl Fn([f64; 2]) -> [f64; 2],
        source_metres_per_pixel: f64,
    ) -> Vec<[u8; 3]> {
        let k = (self.metres_per_pixel / source_metres_per_pixel)
            .ceil()
            .clamp(1.0, 4.0) as usize;
        let mut out = Vec::with_capacity(self.size * self.size);
        for y in 0..self.size {
            for x in 0..self.size {
                let mut sum = [0.0f32; 3];
                for sy in 0..k {
                    for sx in 0..k {
                        let fx = x as f64 + (sx as f64 + 0.5) / k as f64;
                        let fy = y as f64 + (sy as f64 + 0.5) / k as f64;
                        let p = to_pixel(self.world_at(fx, fy));
                        let c = image.bilinear(p[0], p[1]);
                        for ch in 0..3 {
                            sum[ch] += c[ch];
                        }
                    }
                }
                let n = (k * k) as f32;
                out.push(sum.map(|s| linear_to_srgb8(s / n)));
            }
        }
        out
    }

    /// The footprint mask: 255 where the pixel centre is inside the rings (even-odd, so holes
    /// given as rings are outside), else 0.
    pub fn mask(&self, rings: &[Vec<[f64; 2]>]) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.size * self.size);
        for y in 0..self.size {
            for x in 0..self.size {
                let p = self.world_at(x as f64 + 0.5, y as f64 + 0.5);
                let inside = rings.iter().filter(|r| crosses_odd(r, p)).count() % 2 == 1;
                out.push(if inside { 255 } else { 0 });
            }
        }
        out
    }
}

/// Whether a ray from `p` towards +x crosses the ring an odd number of times.
fn crosses_odd(ring: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut inside = false;
    let n = ring.len();
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// A rotated rectangle: centre, unit axis along its long side, long and short side lengths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotatedRect {
    pub centre: [f64; 2],
    pub axis: [f64; 2],
    pub length: f64,
    pub width: f64,
}

/// The smallest-area rectangle around the points (rotating calipers over the convex hull), with
/// its axis along the long side, pointing east-ish (`axis.x > 0`, or north when exactly
/// vertical). `None` for fewer than 3 distinct points, no area, or non-finite input.
pub fn min_rotated_rect(points: &[[f64; 2]]) -> Option<RotatedRect> {
    if points
        .iter()
        .any(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return None;
    }
    let hull = convex_hull(points);
    if hull.len() < 3 {
        return None;
    }
    let mut best: Option<(f64, RotatedRect)> = None;
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        if len == 0.0 {
            continue;
        }
        let (ux, uy) = (dx / len, dy / len);
        let (mut u0, mut u1, mut v0, mut v1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in &hull {
            let u = p[0] * ux + p[1] * uy;
            let v = -p[0] * uy + p[1] * ux;
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(v);
            v1 = v1.max(v);
        }
        let (lu, lv) = (u1 - u0, v1 - v0);
        let area = lu * lv;
        if area.is_nan() || area <= 0.0 {
            continue;
        }
        let (cu, cv) = ((u0 + u1) / 2.0, (v0 + v1) / 2.0);
        let centre = [cu * ux - cv * uy, cu * uy + cv * ux];
        let (axis, length, width) = if lu >= lv {
            ([ux, uy], lu, lv)
        } else {
            ([-uy, ux], lv, lu)
        };
        let axis = if axis[0] < -1e-12 || (axis[0].abs() <= 1e-12 && axis[1] < 0.0) {
            [-axis[0], -axis[1]]
        } else {
            axis
        };
        let rect = RotatedRect {
            centre,
            axis,
            length,
            width,
        };
        if best.is_none_or(|(a, _)| area < a - 1e-9 * a) {
            best = Some((area, rect));
        }
    }
    best.map(|(_, r)| r)
}

/// The convex hull, counter-clockwise, without collinear points (Andrew's monotone chain).
fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p: Vec<[f64; 2]> = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// The dominant edge direction of an image, modulo 90 degrees, in radians in (-pi/4, pi/4] (y up),
/// from gradients weighted towards the centre; `None` when the image has no clear direction.
/// Used to turn a crop without a footprint so its building's sides are axis-aligned.
pub fn dominant_direction(image: &Image) -> Option<f64> {
    let (w, h) = (image.width, image.height);
    if w < 3 || h < 3 {
        return None;
    }
    // Luminance, smoothed so staircase edges do not pull towards the pixel axes.
    let mut l: Vec<f64> = image
        .pixels
        .iter()
        .map(|p| f64::from(0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]))
        .collect();
    for _ in 0..2 {
        for horizontal in [true, false] {
            let src = l.clone();
            for y in 0..h {
                for x in 0..w {
                    let at = |d: i64| {
                        let (sx, sy) = if horizontal {
                            ((x as i64 + d).clamp(0, w as i64 - 1) as usize, y)
                        } else {
                            (x, (y as i64 + d).clamp(0, h as i64 - 1) as usize)
                        };
                        src[sy * w + sx]
                    };
                    l[y * w + x] =
                        (at(-2) + 4.0 * at(-1) + 6.0 * at(0) + 4.0 * at(1) + at(2)) / 16.0;
                }
            }
        }
    }
    let lum = |x: usize, y: usize| l[y * w + x];
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let sigma2 = (w.min(h) as f64 / 3.0).powi(2);
    let (mut c, mut s, mut total) = (0.0, 0.0, 0.0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let gx = lum(x + 1, y) - lum(x - 1, y);
            let gy = lum(x, y - 1) - lum(x, y + 1);
            let m2 = gx * gx + gy * gy;
            if m2 == 0.0 {
                continue;
            }
            let r2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
            let weight = m2 * (-r2 / (2.0 * sigma2)).exp();
            let theta = gy.atan2(gx);
            c += weight * (4.0 * theta).cos();
            s += weight * (4.0 * theta).sin();
            total += weight;
        }
    }
    if total.is_nan() || total <= 0.0 || c.hypot(s) < 0.15 * total {
        return None;
    }
    Some(s.atan2(c) / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_rotated_rectangle_is_found_exactly() {
        // 20 x 8 m, turned 30 degrees, centred at (5, -3).
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let pts: Vec<[f64; 2]> = [[-10.0, -4.0], [10.0, -4.0], [10.0, 4.0], [-10.0, 4.0]]
            .iter()
            .map(|p| [5.0 + p[0] * c - p[1] * s, -3.0 + p[0] * s + p[1] * c])
            .collect();
        let r = min_rotated_rect(&pts).expect("a rectangle");
        assert!((r.length - 20.0).abs() < 1e-9 && (r.width - 8.0).abs() < 1e-9);
        assert!((r.centre[0] - 5.0).abs() < 1e-9 && (r.centre[1] + 3.0).abs() < 1e-9);
        assert!((r.axis[0] - c).abs() < 1e-9 && (r.axis[1] - s).abs() < 1e-9);
    }

    #[test]
    fn the_frame_puts_the_long_side_horizontal_at_the_fill_share() {
        // A 14 x 6 m house running north-south: the crop turns it to horizontal.
        let outer = [[-3.0, -7.0], [3.0, -7.0], [3.0, 7.0], [-3.0, 7.0]];
        let rule = CropRule {
            size: 20,
            fill: 0.7,
        };
        let f = CropFrame::of_footprint(&outer, rule).expect("a frame");
        assert_eq!(f.axis, [0.0, 1.0]);
        assert!((f.metres_per_pixel - 1.0).abs() < 1e-12);
        let mask = f.mask(&[outer.to_vec()]);
        // 14 of 20 columns and 6 of 20 rows are inside.
        let inside_cols = (0..20).filter(|&x| mask[10 * 20 + x] == 255).count();
        let inside_rows = (0..20).filter(|&y| mask[y * 20 + 10] == 255).count();
        assert_eq!((inside_cols, inside_rows), (14, 6));
    }

    #[test]
    fn degenerate_footprints_have_no_frame() {
        let rule = CropRule::MODEL;
        assert!(CropFrame::of_footprint(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], rule).is_none());
        assert!(CropFrame::of_footprint(&[[0.0, 0.0], [1.0, 0.0]], rule).is_none());
        assert!(
            CropFrame::of_footprint(&[[0.0, 0.0], [1.0, 0.0], [f64::NAN, 1.0]], rule).is_none()
        );
    }

    #[test]
    fn the_dominant_direction_of_a_turned_square_is_its_turn() {
        let size = 64;
        let mut img = Image::filled(size, size, [0.1; 3]);
        let turn = 20f64.to_radians();
        for y in 0..size {
            for x in 0..size {
                let (u, v) = (x as f64 + 0.5 - 32.0, 32.0 - (y as f64 + 0.5));
                let (a, b) = (
                    u * turn.cos() + v * turn.sin(),
                    -u * turn.sin() + v * turn.cos(),
                );
                if a.abs() < 15.0 && b.abs() < 9.0 {
                    img.pixels[y * size + x] = [0.8; 3];
                }
            }
        }
        let d = dominant_direction(&img).expect("a direction");
        assert!((d - turn).abs() < 2f64.to_radians(), "{}", d.to_degrees());
        assert_eq!(dominant_direction(&Image::filled(8, 8, [0.5; 3])), None);
    }

    proptest! {
        #[test]
        fn every_point_lies_in_the_rectangle(
            pts in proptest::collection::vec((-50.0f64..50.0, -50.0f64..50.0), 3..30)
        ) {
            let pts: Vec<[f64; 2]> = pts.into_iter().map(|(x, y)| [x, y]).collect();
            if let Some(r) = min_rotated_rect(&pts) {
                prop_assert!(r.length >= r.width);
                let perp = [-r.axis[1], r.axis[0]];
                for p in &pts {
                    let d = [p[0] - r.centre[0], p[1] - r.centre[1]];
                    let u = d[0] * r.axis[0] + d[1] * r.axis[1];
                    let v = d[0] * perp[0] + d[1] * perp[1];
                    prop_assert!(u.abs() <= r.length / 2.0 + 1e-7);
                    prop_assert!(v.abs() <= r.width / 2.0 + 1e-7);
                }
                // No larger than the axis-aligned box.
                let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
                for p in &pts { for k in 0..2 { lo[k] = lo[k].min(p[k]); hi[k] = hi[k].max(p[k]); } }
                prop_assert!(r.length * r.width <= (hi[0] - lo[0]) * (hi[1] - lo[1]) + 1e-7);
            }
        }
    }
}

//! An orthographic, top-down rasteriser for citymesh meshes: a parallel projection from above
//! (straight down, or off nadir by a skew), a depth buffer, flat shading from face normals under a
//! sun and a sky, and cast shadows from a shadow map rendered along the sun's rays. Pure and
//! deterministic; no GPU.

use super::image::Image;
use crate::mesh::{Mesh, triangle_normal};

/// The view: which ground area the image covers and how it looks at it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// `[east, north]` metres of the image's top-left corner.
    pub top_left: [f64; 2],
    /// Ground size of one pixel.
    pub metres_per_pixel: f64,
    pub width: usize,
    pub height: usize,
    /// Off-nadir view: a point `h` metres up appears displaced by `skew * h` on the ground (0 for
    /// straight down; 0.2 is about 11 degrees off nadir).
    pub skew: [f64; 2],
}

impl Camera {
    /// Pixel coordinates (centres at `i + 0.5`) of a world point.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        [
            (p[0] + self.skew[0] * p[2] - self.top_left[0]) / self.metres_per_pixel,
            (self.top_left[1] - (p[1] + self.skew[1] * p[2])) / self.metres_per_pixel,
        ]
    }

    /// How close a world point is to the camera (larger is closer).
    #[inline]
    fn depth(&self, p: [f64; 3]) -> f64 {
        p[2] - self.skew[0] * p[0] - self.skew[1] * p[1]
    }

    /// The world `[east, north]` at pixel coordinates, on the ground plane.
    #[inline]
    pub fn ground_at(&self, x: f64, y: f64) -> [f64; 2] {
        [
            self.top_left[0] + x * self.metres_per_pixel,
            self.top_left[1] - y * self.metres_per_pixel,
        ]
    }
}

/// The sun: where it stands and how strong it is against the sky.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sun {
    /// Degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Degrees above the horizon (clamped to at least 5).
    pub elevation_deg: f64,
    /// Share of the light that comes from the sky and reaches shadows too, in [0, 1].
    pub ambient: f32,
}

impl Sun {
    /// The unit vector towards the sun.
    pub fn direction(&self) -> [f64; 3] {
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.max(5.0).to_radians(),
        );
        [az.sin() * el.cos(), az.cos() * el.cos(), el.sin()]
    }
}

/// The colour of a surface before lighting, per triangle and point.
pub trait Albedo {
    /// The linear-light albedo of triangle `triangle` at world point `p`; `normal` is the
    /// triangle's unit normal.
    fn albedo(&self, triangle: usize, p: [f64; 3], normal: [f64; 3]) -> [f32; 3];

    /// Where two faces of one group meet at an angle (a roof's ridges, hips and valleys), pixels
    /// are multiplied by the group's factor: ridge tiles and flashing show as lines. `None` for
    /// triangles without creases.
    fn crease(&self, _triangle: usize) -> Option<(u32, f32)> {
        None
    }
}

/// What the rasteriser found at each pixel.
struct Frame {
    depth: Vec<f64>,
    triangle: Vec<u32>,
    point: Vec<[f64; 3]>,
}

const NONE: u32 = u32::MAX;

/// Renders `mesh` as seen by `camera` under `sun`. Pixels no triangle covers are black.
pub fn render(mesh: &Mesh, camera: &Camera, sun: &Sun, albedo: &impl Albedo) -> Image {
    let normals: Vec<[f64; 3]> = mesh
        .triangles
        .iter()
        .map(|&t| {
            let [a, b, c] = mesh.corners(t);
            unit(triangle_normal(a, b, c))
        })
        .collect();
    let frame = rasterise(
        mesh,
        camera.width,
        camera.height,
        |p| camera.project(p),
        |p| camera.depth(p),
    );
    let mut creases = creases(&frame, &normals, camera.width, camera.height, albedo);
    // Ridge tiles are about 0.3 m wide: thicker lines on finer imagery.
    let width = (0.3 / camera.metres_per_pixel).round().clamp(1.0, 3.0) as usize;
    for _ in 1..width {
        creases = widen(&creases, &frame, camera.width, camera.height);
    }
    let shadows = ShadowMap::new(mesh, sun.direction(), camera.metres_per_pixel);
    let s = sun.direction();
    let mut image = Image::filled(camera.width, camera.height, [0.0; 3]);
    for (i, px) in image.pixels.iter_mut().enumerate() {
        let t = frame.triangle[i];
        if t == NONE {
            continue;
        }
        let (t, p) = (t as usize, frame.point[i]);
        let n = normals[t];
        let direct = dot(n, s).max(0.0);
        let lit = if direct > 0.0 && shadows.is_lit(p) {
            direct
        } else {
            0.0
        };
        // Exposed for open ground: a horizontal surface in the sun gets the same light at any
        // sun elevation; slopes facing the sun are brighter, up to a point.
        let direct = (lit / s[2].max(0.2)).min(1.6) as f32 * 0.6;
        let light = sun.ambient + (1.0 - sun.ambient) * direct;
        let a = albedo.albedo(t, p, n);
        let crease = creases[i];
        *px = a.map(|c| c * light * crease);
    }
    image
}

/// The crease factor of every pixel: the group's factor where a pixel and its right or lower
/// neighbour show faces of the same group at an angle, else 1.
fn creases(
    frame: &Frame,
    normals: &[[f64; 3]],
    width: usize,
    height: usize,
    albedo: &impl Albedo,
) -> Vec<f32> {
    let mut out = vec![1.0f32; width * height];
    let group = |i: usize| {
        let t = frame.triangle[i];
        if t == NONE {
            None
        } else {
            albedo.crease(t as usize).map(|g| (t as usize, g))
        }
    };
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let Some((t, (g, factor))) = group(i) else {
                continue;
            };
            for j in [
                (x + 1 < width).then(|| i + 1),
                (y + 1 < height).then(|| i + width),
            ]
            .into_iter()
            .flatten()
            {
                if let Some((t2, (g2, _))) = group(j)
                    && g2 == g
                    && t2 != t
                    && dot(normals[t], normals[t2]) < 0.999
                {
                    out[i] = factor;
                    out[j] = factor;
                }
            }
        }
    }
    out
}

/// Creases grown by one pixel into neighbouring pixels that show a triangle.
fn widen(creases: &[f32], frame: &Frame, width: usize, height: usize) -> Vec<f32> {
    let mut out = creases.to_vec();
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if creases[i] != 1.0 || frame.triangle[i] == NONE {
                continue;
            }
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < width).then(|| i + 1),
                (y > 0).then(|| i - width),
                (y + 1 < height).then(|| i + width),
            ];
            if let Some(j) = neighbours
                .into_iter()
                .flatten()
                .find(|&j| creases[j] != 1.0)
            {
                out[i] = creases[j];
            }
        }
    }
    out
}

/// Scan-converts every triangle under a parallel projection, keeping the closest.
fn rasterise(
    mesh: &Mesh,
    width: usize,
    height: usize,
    project: impl Fn([f64; 3]) -> [f64; 2],
    depth: impl Fn([f64; 3]) -> f64,
) -> Frame {
    let mut frame = Frame {
        depth: vec![f64::NEG_INFINITY; width * height],
        triangle: vec![NONE; width * height],
        point: vec![[0.0; 3]; width * height],
    };
    let screen: Vec<[f64; 2]> = mesh.positions.iter().map(|&p| project(p)).collect();
    let depths: Vec<f64> = mesh.positions.iter().map(|&p| depth(p)).collect();
    for (ti, &t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| screen[i as usize]);
        let area = edge(a, b, c);
        if area.abs() < 1e-9 || !area.is_finite() {
            continue;
        }
        let x0 = a[0].min(b[0]).min(c[0]).floor().max(0.0);
        let x1 = a[0].max(b[0]).max(c[0]).ceil().min(width as f64);
        let y0 = a[1].min(b[1]).min(c[1]).floor().max(0.0);
        let y1 = a[1].max(b[1]).max(c[1]).ceil().min(height as f64);
        if x0 >= x1 || y0 >= y1 {
            continue;
        }
        let d = t.map(|i| depths[i as usize]);
        let w = mesh.corners(t);
        for y in y0 as usize..y1 as usize {
            for x in x0 as usize..x1 as usize {
                let p = [x as f64 + 0.5, y as f64 + 0.5];
                let l0 = edge(b, c, p) / area;
                let l1 = edge(c, a, p) / area;
                let l2 = 1.0 - l0 - l1;
                if l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9 {
                    continue;
                }
                let z = l0 * d[0] + l1 * d[1] + l2 * d[2];
                let i = y * width + x;
                if z > frame.depth[i] {
                    frame.depth[i] = z;
                    frame.triangle[i] = ti as u32;
                    frame.point[i] =
                        std::array::from_fn(|k| l0 * w[0][k] + l1 * w[1][k] + l2 * w[2][k]);
                }
            }
        }
    }
    frame
}

/// Depth along the sun's rays, seen from the sun, over the mesh's extent.
struct ShadowMap {
    sun: [f64; 3],
    origin: [f64; 2],
    cell: f64,
    width: usize,
    height: usize,
    depth: Vec<f64>,
}

/// The shadow map's longest side in cells; coarser cells beyond that.
const MAX_SHADOW_SIDE: usize = 1024;

impl ShadowMap {
    fn new(mesh: &Mesh, sun: [f64; 3], cell: f64) -> Self {
        let project = |p: [f64; 3]| -> [f64; 2] {
            [p[0] - p[2] * sun[0] / sun[2], p[1] - p[2] * sun[1] / sun[2]]
        };
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &p in &mesh.positions {
            let q = project(p);
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
            return Self {
                sun,
                origin: [0.0; 2],
                cell: 1.0,
                width: 0,
                height: 0,
                depth: Vec::new(),
            };
        }
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let cell = cell.max(side / MAX_SHADOW_SIDE as f64).max(1e-3);
        let width = ((hi[0] - lo[0]) / cell).ceil() as usize + 2;
        let height = ((hi[1] - lo[1]) / cell).ceil() as usize + 2;
        let origin = [lo[0] - cell, hi[1] + cell];
        let to_cell = |p: [f64; 3]| {
            let q = project(p);
            [(q[0] - origin[0]) / cell, (origin[1] - q[1]) / cell]
        };
        let frame = rasterise(mesh, width, height, to_cell, |p| dot(p, sun));
        Self {
            sun,
            origin,
            cell,
            width,
            height,
            depth: frame.depth,
        }
    }

    /// Whether nothing stands between `p` and the sun.
    fn is_lit(&self, p: [f64; 3]) -> bool {
        let s = self.sun;
        let q = [p[0] - p[2] * s[0] / s[2], p[1] - p[2] * s[1] / s[2]];
        let x = ((q[0] - self.origin[0]) / self.cell).floor();
        let y = ((self.origin[1] - q[1]) / self.cell).floor();
        if x < 0.0 || y < 0.0 || x >= self.width as f64 || y >= self.height as f64 {
            return true;
        }
        let blocker = self.depth[y as usize * self.width + x as usize];
        // A cell's worth of slope plus a little: surfaces do not shadow themselves.
        blocker <= dot(p, s) + 0.2 + 1.5 * self.cell
    }
}

#[inline]
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

#[inline]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let l = dot(v, v).sqrt();
    if l > 0.0 {
        v.map(|c| c / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceStyle, Material, Rgb};

    struct White;
    impl Albedo for White {
        fn albedo(&self, _: usize, _: [f64; 3], _: [f64; 3]) -> [f32; 3] {
            [1.0; 3]
        }
    }

    /// A box `[x0, x1] x [y0, y1] x [0, h]`, faces counter-clockwise from outside, on a ground
    /// square of side `g` around the origin.
    fn box_on_ground(x0: f64, x1: f64, y0: f64, y1: f64, h: f64, g: f64) -> Mesh {
        let mut m = Mesh::default();
        let style = FaceStyle::plain(Material::Wall, Rgb(255, 255, 255));
        let quad = |m: &mut Mesh, q: [[f64; 3]; 4]| {
            let i = q.map(|p| m.push_vertex(p));
            m.push_triangle([i[0], i[1], i[2]], style);
            m.push_triangle([i[0], i[2], i[3]], style);
        };
        quad(
            &mut m,
            [[-g, -g, 0.0], [g, -g, 0.0], [g, g, 0.0], [-g, g, 0.0]],
        );
        quad(&mut m, [[x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h]]);
        quad(
            &mut m,
            [[x0, y0, 0.0], [x1, y0, 0.0], [x1, y0, h], [x0, y0, h]],
        );
        quad(
            &mut m,
            [[x1, y0, 0.0], [x1, y1, 0.0], [x1, y1, h], [x1, y0, h]],
        );
        quad(
            &mut m,
            [[x1, y1, 0.0], [x0, y1, 0.0], [x0, y1, h], [x1, y1, h]],
        );
        quad(
            &mut m,
            [[x0, y1, 0.0], [x0, y0, 0.0], [x0, y0, h], [x0, y1, h]],
        );
        m
    }

    fn camera(size: usize, mpp: f64) -> Camera {
        let half = size as f64 * mpp / 2.0;
        Camera {
            top_left: [-half, half],
            metres_per_pixel: mpp,
            width: size,
            height: size,
            skew: [0.0, 0.0],
        }
    }

    #[test]
    fn a_box_casts_a_shadow_away_from_the_sun_of_the_right_length() {
        // A 4 m cube at the centre; the sun in the south at 45 degrees: the shadow falls north,
        // 4 m long (tan 45 = 1).
        let mesh = box_on_ground(-2.0, 2.0, -2.0, 2.0, 4.0, 20.0);
        let cam = camera(40, 0.5);
        let sun = Sun {
            azimuth_deg: 180.0,
            elevation_deg: 45.0,
            ambient: 0.3,
        };
        let img = render(&mesh, &cam, &sun, &White);
        let at = |x: f64, y: f64| {
            let p = cam.project([x, y, 0.0]);
            img.get(p[0] as usize, p[1] as usize)[0]
        };
        let shade = 0.3f32;
        // North of the box, within 4 m: in shadow (ambient only).
        assert!((at(0.0, 3.0) - shade).abs() < 1e-5, "{}", at(0.0, 3.0));
        assert!((at(0.0, 5.5) - shade).abs() < 1e-5, "{}", at(0.0, 5.5));
        // Beyond the shadow, and south of the box: lit.
        assert!(at(0.0, 7.0) > 0.5, "{}", at(0.0, 7.0));
        assert!(at(0.0, -4.0) > 0.5, "{}", at(0.0, -4.0));
        // East of the shadow: lit.
        assert!(at(4.0, 4.0) > 0.5);
        // The roof is lit the same as open ground (both horizontal).
        assert_eq!(at(0.0, 0.0), at(0.0, -6.0));
    }

    #[test]
    fn off_nadir_views_show_the_wall_facing_the_camera() {
        // Seen from the east: points up high move west, so the east wall faces the camera and
        // the box's roof lands 2 m (0.5 * 4 m) west of its footprint.
        let mesh = box_on_ground(-2.0, 2.0, -2.0, 2.0, 4.0, 20.0);
        let mut cam = camera(40, 0.5);
        cam.skew = [-0.5, 0.0];
        let frame = rasterise(&mesh, 40, 40, |p| cam.project(p), |p| cam.depth(p));
        let tri_at = |x: f64, y: f64| {
            let p = cam.project([x, y, 0.0]);
            frame.triangle[p[1] as usize * 40 + p[0] as usize]
        };
        // Ground under the roof's displaced image at x = -3.5: roof triangles are 2 and 3.
        assert!([2, 3].contains(&tri_at(-3.5, 0.0)), "{}", tri_at(-3.5, 0.0));
        // Between x = 0 and 2 the east wall (triangles 6, 7) is seen.
        assert!([6, 7].contains(&tri_at(1.0, 0.0)), "{}", tri_at(1.0, 0.0));
        // East of the footprint: ground.
        assert!([0, 1].contains(&tri_at(3.0, 0.0)));
    }
}

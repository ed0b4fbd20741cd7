//! How a scene looks: ground, roads and palettes ([`Look`]), and each roof's surface: colour,
//! texture, weathering, solar panels and parapet ([`RoofLook`]).

use super::Palette;
use crate::building::roof::RoofShape;
use crate::roof_image::image::srgb8_to_linear;
use crate::roof_image::noise;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// What every surface of a scene looks like.
#[derive(Debug, Clone)]
pub(super) struct Look {
    pub(super) palette: Palette,
    pub(super) grass: [f32; 3],
    pub(super) soil: [f32; 3],
    pub(super) paving: [f32; 3],
    /// Roads: unit direction, offset of the centre line from the origin, half-width.
    pub(super) roads: Vec<([f64; 2], f64, f64)>,
    pub(super) ground_seed: u64,
}

/// The texture of a roof.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum RoofTexture {
    /// Rows of tiles along the eaves, `spacing` metres apart.
    Tiles {
        spacing: f64,
    },
    /// Standing seams down the slope (or along the axis on flat roofs).
    Seams {
        spacing: f64,
    },
    Gravel,
    Membrane {
        seam: f64,
    },
    Plain,
    Green,
}

/// A roof's surface: base colour, texture, weathering, solar panels and parapet.
#[derive(Debug, Clone)]
pub(super) struct RoofLook {
    pub(super) colour: [f32; 3],
    pub(super) texture: RoofTexture,
    pub(super) contrast: f32,
    pub(super) weathering: f32,
    pub(super) seed: u64,
    /// Solar panels: the facing (unit downslope direction, or `None` on a flat roof) and a
    /// rectangle `[u0, u1, v0, v1]` in the footprint's axes around its centre.
    pub(super) panels: Option<(Option<[f64; 2]>, [f64; 4])>,
    pub(super) parapet: Option<(f64, [f32; 3])>,
    /// Brightness of ridges, hips and valleys against the roof.
    pub(super) ridge: f32,
    pub(super) outer: Vec<[f64; 2]>,
    pub(super) centre: [f64; 2],
    pub(super) axis: [f64; 2],
}

pub(super) fn linear(c: [u8; 3]) -> [f32; 3] {
    c.map(srgb8_to_linear)
}

/// A colour from the list, jittered in brightness and per channel.
pub(super) fn pick(rng: &mut ChaCha8Rng, list: &[[u8; 3]]) -> [f32; 3] {
    let base = linear(list[rng.random_range(0..list.len())]);
    let bright = rng.random_range(0.75..1.25f32);
    base.map(|c| (c * bright * rng.random_range(0.9..1.1f32)).min(1.0))
}

pub(super) const TRAIN_PITCHED: [[u8; 3]; 7] = [
    [168, 74, 52],
    [140, 62, 45],
    [120, 72, 55],
    [92, 90, 92],
    [58, 58, 64],
    [110, 58, 48],
    [150, 96, 70],
];
pub(super) const TRAIN_FLAT: [[u8; 3]; 6] = [
    [170, 170, 168],
    [205, 205, 200],
    [140, 134, 124],
    [72, 72, 74],
    [118, 118, 112],
    [150, 140, 128],
];
pub(super) const HOLDOUT_PITCHED: [[u8; 3]; 6] = [
    [190, 100, 66],
    [84, 92, 108],
    [138, 112, 92],
    [92, 134, 118],
    [40, 40, 42],
    [160, 60, 60],
];
pub(super) const HOLDOUT_FLAT: [[u8; 3]; 6] = [
    [196, 186, 166],
    [96, 96, 100],
    [228, 228, 226],
    [150, 122, 104],
    [162, 166, 172],
    [60, 62, 58],
];
pub(super) const WALLS: [[u8; 3]; 5] = [
    [220, 210, 190],
    [200, 180, 150],
    [170, 120, 100],
    [190, 190, 185],
    [230, 225, 215],
];

impl Look {
    pub(super) fn draw(rng: &mut ChaCha8Rng, palette: Palette) -> Self {
        let (grass, soil, paving) = match palette {
            Palette::Training => (
                pick(rng, &[[88, 110, 60], [70, 96, 52], [104, 118, 72]]),
                pick(rng, &[[120, 100, 78], [100, 92, 80]]),
                pick(rng, &[[110, 110, 112], [130, 128, 124], [90, 90, 94]]),
            ),
            Palette::Holdout => (
                pick(rng, &[[128, 124, 80], [96, 104, 66], [140, 130, 96]]),
                pick(rng, &[[150, 120, 90], [128, 110, 96]]),
                pick(rng, &[[150, 120, 110], [100, 104, 110], [170, 166, 156]]),
            ),
        };
        let roads = (0..rng.random_range(0..3))
            .map(|_| {
                let a: f64 = rng.random_range(0.0..std::f64::consts::PI);
                (
                    [a.cos(), a.sin()],
                    rng.random_range(-40.0..40.0),
                    rng.random_range(2.5..7.0),
                )
            })
            .collect();
        Self {
            palette,
            grass,
            soil,
            paving,
            roads,
            ground_seed: rng.random(),
        }
    }

    /// A neighbour's roof: any of the shapes citymesh builds, mostly the common ones.
    pub(super) fn neighbour_shape(&self, rng: &mut ChaCha8Rng) -> RoofShape {
        let weights = [
            (RoofShape::Flat, 4),
            (RoofShape::Gabled, 4),
            (RoofShape::Hipped, 3),
        ];
        let extra = [
            RoofShape::Pyramidal,
            RoofShape::Skillion,
            RoofShape::HalfHipped,
            RoofShape::Gambrel,
            RoofShape::Mansard,
        ];
        if rng.random_bool(0.15) {
            return extra[rng.random_range(0..extra.len())];
        }
        let total: u32 = weights.iter().map(|w| w.1).sum();
        let mut pick = rng.random_range(0..total);
        for (s, w) in weights {
            if pick < w {
                return s;
            }
            pick -= w;
        }
        RoofShape::Flat
    }

    pub(super) fn roof(
        &self,
        rng: &mut ChaCha8Rng,
        shape: RoofShape,
        outer: &[[f64; 2]],
    ) -> RoofLook {
        let flat = shape == RoofShape::Flat;
        let colours: &[[u8; 3]] = match (self.palette, flat) {
            (Palette::Training, false) => &TRAIN_PITCHED,
            (Palette::Training, true) => &TRAIN_FLAT,
            (Palette::Holdout, false) => &HOLDOUT_PITCHED,
            (Palette::Holdout, true) => &HOLDOUT_FLAT,
        };
        // A fifth of roofs take the other kind's colour, so colour alone does not give the class.
        let colour = if rng.random_bool(0.2) {
            let other: &[[u8; 3]] = match (self.palette, flat) {
                (Palette::Training, false) => &TRAIN_FLAT,
                (Palette::Training, true) => &TRAIN_PITCHED,
                (Palette::Holdout, false) => &HOLDOUT_FLAT,
                (Palette::Holdout, true) => &HOLDOUT_PITCHED,
            };
            pick(rng, other)
        } else {
            pick(rng, colours)
        };
        let texture = if flat {
            match rng.random_range(0..10) {
                0..=3 => RoofTexture::Gravel,
                4..=6 => RoofTexture::Membrane {
                    seam: rng.random_range(1.0..2.5),
                },
                7 => RoofTexture::Green,
                8 => RoofTexture::Seams {
                    spacing: rng.random_range(0.5..1.0),
                },
                _ => RoofTexture::Plain,
            }
        } else {
            match rng.random_range(0..10) {
                0..=5 => RoofTexture::Tiles {
                    spacing: rng.random_range(0.25..0.45),
                },
                6 | 7 => RoofTexture::Seams {
                    spacing: rng.random_range(0.4..0.7),
                },
                _ => RoofTexture::Plain,
            }
        };
        let rect = crate::roof_image::crop::min_rotated_rect(outer);
        let (centre, axis, length, width) = rect.map_or(([0.0; 2], [1.0, 0.0], 10.0, 10.0), |r| {
            (r.centre, r.axis, r.length, r.width)
        });
        let panels = rng.random_bool(if flat { 0.15 } else { 0.25 }).then(|| {
            let u0 = rng.random_range(-0.45..0.1) * length;
            let u1 = u0 + rng.random_range(0.2..0.5) * length;
            let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let v = [
                side * 0.05 * width,
                side * rng.random_range(0.3..0.45) * width,
            ];
            let facing = (!flat).then(|| {
                let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                [a.cos(), a.sin()]
            });
            (facing, [u0, u1, v[0].min(v[1]), v[0].max(v[1])])
        });
        let parapet = (flat && rng.random_bool(0.6)).then(|| {
            let tone = rng.random_range(0.6..1.5f32);
            (
                rng.random_range(0.25..0.6),
                colour.map(|c| (c * tone).min(1.0)),
            )
        });
        let ridge = if rng.random_bool(0.5) {
            rng.random_range(0.5..0.85)
        } else {
            rng.random_range(1.15..1.6)
        };
        RoofLook {
            ridge,
            colour,
            texture,
            contrast: rng.random_range(0.05..0.3),
            weathering: rng.random_range(0.0..0.35),
            seed: rng.random(),
            panels,
            parapet,
            outer: outer.to_vec(),
            centre,
            axis,
        }
    }
}

impl RoofLook {
    pub(super) fn albedo(&self, p: [f64; 3], normal: [f64; 3]) -> [f32; 3] {
        let flat = normal[2] > 0.995;
        let (x, y) = (p[0], p[1]);
        // Footprint axes: u along the long side, v across.
        let d = [x - self.centre[0], y - self.centre[1]];
        let u = d[0] * self.axis[0] + d[1] * self.axis[1];
        let v = -d[0] * self.axis[1] + d[1] * self.axis[0];
        if let Some((facing, [u0, u1, v0, v1])) = self.panels {
            let faces = match facing {
                None => flat,
                Some(f) => !flat && normal[0] * f[0] + normal[1] * f[1] > 0.0,
            };
            if faces && u > u0 && u < u1 && v > v0 && v < v1 {
                let grid = (u - u0).rem_euclid(1.05) < 0.06 || (v - v0).rem_euclid(1.7) < 0.06;
                return if grid {
                    [0.25, 0.26, 0.28]
                } else {
                    [0.025, 0.035, 0.06]
                };
            }
        }
        if let Some((width, colour)) = self.parapet
            && flat
            && distance_to_ring(&self.outer, [x, y]) < width
        {
            return colour;
        }
        let down = {
            let l = normal[0].hypot(normal[1]);
            if l > 1e-6 {
                [normal[0] / l, normal[1] / l]
            } else {
                self.axis
            }
        };
        let along_slope = x * down[0] + y * down[1];
        let across_slope = -x * down[1] + y * down[0];
        let k = self.contrast;
        let pattern = match self.texture {
            RoofTexture::Tiles { spacing } => {
                let row = (along_slope / spacing).rem_euclid(1.0);
                let tile = (across_slope / (spacing * 0.8) + 0.5 * (along_slope / spacing).floor())
                    .rem_euclid(1.0);
                1.0 - k * (if row < 0.25 { 1.0 } else { 0.0 } + if tile < 0.12 { 0.5 } else { 0.0 })
            }
            RoofTexture::Seams { spacing } => {
                let s = (across_slope / spacing).rem_euclid(1.0);
                if s < 0.12 { 1.0 + k } else { 1.0 }
            }
            RoofTexture::Gravel => {
                0.85 + 0.3 * noise::value(x * 6.0, y * 6.0, self.seed) * (1.0 + k)
            }
            RoofTexture::Membrane { seam } => {
                if (u / seam).rem_euclid(1.0) < 0.06 {
                    1.0 - k
                } else {
                    1.0
                }
            }
            RoofTexture::Plain => 1.0,
            RoofTexture::Green => {
                let n = noise::fractal(x, y, 3, self.seed);
                return [0.08 + 0.1 * n, 0.14 + 0.12 * n, 0.05 + 0.04 * n];
            }
        };
        let stain = noise::fractal(x / 4.0, y / 4.0, 3, self.seed ^ 11);
        let weather = 1.0 - self.weathering * (stain - 0.3).max(0.0) * 1.4;
        let moss = self.weathering > 0.25 && stain > 0.78;
        let base = if moss { [0.09, 0.1, 0.05] } else { self.colour };
        base.map(|c| (c * pattern * weather).max(0.0))
    }
}

pub(super) fn distance_to_ring(ring: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| crate::building::footprint::segment_distance(p, ring[i], ring[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min)
}

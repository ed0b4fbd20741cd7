//! Randomised training scenes for the roof classifier: one target building with a known roof class
//! among its real (or procedural) neighbours, built by citymesh's own generator, dressed with
//! roof materials and clutter (tile rows, gravel, membranes, metal seams, solar panels, chimneys,
//! dormers, roof units, parapets, weathering), trees as occluders, ground cover and roads, then
//! photographed like imagery: sun and sky, cast shadows, off-nadir skew, 0.1-0.5 m/px, footprint
//! misregistration, colour balance, haze, blur, noise and JPEG artefacts, and cropped by the crop
//! rule. Everything follows from the seed.

use super::class::RoofClass;
use super::crop::{Crop, CropFrame, CropRule};
use super::image::{Image, srgb8_to_linear};
use super::jpeg::jpeg_artefacts;
use super::noise;
use super::render::{Albedo, Camera, Sun, render};
use crate::building::roof::RoofShape;
use crate::building::{BuildingContext, BuildingStats, generate_cluster};
use crate::geo::LocalFrame;
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};
use crate::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use crate::procedural::{ProceduralParams, generate_city};
use crate::terrain::ElevationModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Which colours scenes are drawn from: training renders and the held-out test set use
/// different palettes, so test accuracy is not accuracy on the training colours.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Palette {
    Training,
    Holdout,
}

impl Palette {
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "training" => Some(Palette::Training),
            "holdout" => Some(Palette::Holdout),
            _ => None,
        }
    }
}

/// Footprints to build scenes from: outer rings in metres around one origin, with a coarse grid
/// to find neighbours.
#[derive(Debug, Clone)]
pub struct FootprintPool {
    rings: Vec<Vec<[f64; 2]>>,
    centres: Vec<[f64; 2]>,
    areas: Vec<f64>,
}

/// Footprints smaller or larger than this (m²) are not targets (sheds; halls and blocks).
const TARGET_AREA: (f64, f64) = (40.0, 2500.0);

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

    fn new(rings: Vec<Vec<[f64; 2]>>) -> Self {
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

/// One training sample: the class, the shape drawn, and the crop.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub class: RoofClass,
    pub shape: RoofShape,
    pub crop: Crop,
    /// Ground resolution of the imagery the crop was sampled from.
    pub imagery_metres_per_pixel: f64,
}

/// Share of samples whose footprint mask is given to the model (the rest train the path without
/// one, as `citymesh classify-image` runs on a bare image).
const MASK_SHARE: f64 = 0.7;
/// Longest side of the rendered imagery in pixels; coarser imagery beyond.
const MAX_IMAGERY_SIDE: f64 = 420.0;

/// Renders the sample of `seed` (its class is `seed % 3`, so consecutive seeds are balanced) from a
/// target of `pool`. `None` when the pool has no target or the drawn target cannot be built.
pub fn render_sample(
    pool: &FootprintPool,
    seed: u64,
    palette: Palette,
    rule: CropRule,
) -> Option<Sample> {
    let targets = pool.targets();
    if targets.is_empty() {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0005_EED0_FC1A_55E5);
    let class = RoofClass::ALL[(seed % 3) as usize];
    let target = targets[rng.random_range(0..targets.len())];
    let outer = pool.rings[target].clone();
    let exact = CropFrame::of_footprint(&outer, rule)?;
    let mask_known = rng.random_bool(MASK_SHARE);
    // Without a footprint, the crop is only roughly centred, turned and scaled.
    let frame = if mask_known {
        exact
    } else {
        let turn: f64 = rng.random_range(-12f64..12.0).to_radians();
        let scale = rng.random_range(0.7..1.45);
        let shift = exact.metres_per_pixel * rule.size as f64 * 0.08;
        let [ax, ay] = exact.axis;
        CropFrame {
            centre: [
                exact.centre[0] + rng.random_range(-shift..shift),
                exact.centre[1] + rng.random_range(-shift..shift),
            ],
            axis: [
                ax * turn.cos() - ay * turn.sin(),
                ax * turn.sin() + ay * turn.cos(),
            ],
            metres_per_pixel: exact.metres_per_pixel * scale,
            size: rule.size,
        }
    };
    let look = Look::draw(&mut rng, palette);
    let shape = match class {
        RoofClass::Flat => RoofShape::Flat,
        RoofClass::Gabled => RoofShape::Gabled,
        RoofClass::Hipped => {
            let rect = super::crop::min_rotated_rect(&outer)?;
            if rect.length < 1.3 * rect.width && rng.random_bool(0.4) {
                RoofShape::Pyramidal
            } else {
                RoofShape::Hipped
            }
        }
    };

    // The scene: the target and every footprint near the crop.
    let [lo, hi] = frame.bounds();
    let reach = 25.0;
    let mut scene = SceneBuilder::new(look);
    scene.add_building(&outer, shape, true, &mut rng)?;
    for (i, c) in pool.centres.iter().enumerate() {
        if i == target
            || c[0] < lo[0] - reach
            || c[0] > hi[0] + reach
            || c[1] < lo[1] - reach
            || c[1] > hi[1] + reach
            || overlaps(&pool.rings[i], &outer)
        {
            continue;
        }
        let shape = scene.look.neighbour_shape(&mut rng);
        // A neighbour that cannot be built is left out; the scene still renders.
        let _ = scene.add_building(&pool.rings[i], shape, false, &mut rng);
    }
    scene.add_trees(lo, hi, &outer, &mut rng);
    scene.add_ground(lo, hi, reach + 40.0);

    // The imagery: north-up, covering the crop, shifted against the footprint as real imagery is.
    let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let mpp = rng
        .random_range(0.1..0.5f64)
        .max(extent / MAX_IMAGERY_SIDE)
        .max(frame.metres_per_pixel / 4.0);
    let offset = [rng.random_range(-1.2..1.2), rng.random_range(-1.2..1.2)];
    let skew_size = if rng.random_bool(0.6) {
        rng.random_range(0.0..0.25f64)
    } else {
        0.0
    };
    let skew_dir: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let margin = 4.0 * mpp;
    let camera = Camera {
        top_left: [lo[0] - margin - offset[0], hi[1] + margin - offset[1]],
        metres_per_pixel: mpp,
        width: ((hi[0] - lo[0] + 2.0 * margin) / mpp).ceil() as usize,
        height: ((hi[1] - lo[1] + 2.0 * margin) / mpp).ceil() as usize,
        skew: [skew_size * skew_dir.cos(), skew_size * skew_dir.sin()],
    };
    let sun = Sun {
        azimuth_deg: rng.random_range(0.0..360.0),
        elevation_deg: rng.random_range(25.0..62.0),
        ambient: rng.random_range(0.15..0.35),
    };
    let mut imagery = render(&scene.mesh, &camera, &sun, &scene);
    develop(&mut imagery, &mut rng);

    // The camera's corner holds the misregistration: world w is drawn at (w - top_left) / mpp.
    let to_pixel = |w: [f64; 2]| {
        [
            (w[0] - camera.top_left[0]) / mpp,
            (camera.top_left[1] - w[1]) / mpp,
        ]
    };
    let rgb = frame.sample(&imagery, to_pixel, mpp);
    let mask = mask_known.then(|| frame.mask(std::slice::from_ref(&outer)));
    Some(Sample {
        class,
        shape,
        crop: Crop {
            size: rule.size,
            rgb,
            mask,
        },
        imagery_metres_per_pixel: mpp,
    })
}

/// A synthetic orthophoto of real buildings: every record that is not a part, with the roof
/// shape its `roof:shape` tag names (flat without one), drawn as the training scenes are (one
/// look per `seed`; each building's heights, colours and clutter follow from its id, so
/// neighbouring tiles agree), without trees or sensor effects. `frame` is the local frame the
/// camera's metres are in. For test imagery servers: real footprints, known roof shapes.
pub fn render_orthophoto(
    records: &[BuildingRecord],
    frame: &LocalFrame,
    camera: &Camera,
    palette: Palette,
    seed: u64,
) -> Image {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let look = Look::draw(&mut rng, palette);
    let mut scene = SceneBuilder::new(look);
    scene.frame = *frame;
    let w = camera.width as f64 * camera.metres_per_pixel;
    let h = camera.height as f64 * camera.metres_per_pixel;
    let lo = [camera.top_left[0], camera.top_left[1] - h];
    let hi = [camera.top_left[0] + w, camera.top_left[1]];
    let reach = 40.0;
    for record in records {
        if record.is_part || record.outers.len() != 1 {
            continue;
        }
        let outer = record.outers[0].local_points(frame);
        let near = outer.iter().any(|p| {
            p[0] > lo[0] - reach
                && p[0] < hi[0] + reach
                && p[1] > lo[1] - reach
                && p[1] < hi[1] + reach
        });
        if !near {
            continue;
        }
        let shape = record
            .tags
            .get("roof:shape")
            .and_then(|v| RoofShape::from_tag(v))
            .unwrap_or(RoofShape::Flat);
        let id = match record.id {
            OsmId::Way(i) | OsmId::Relation(i) => i as u64,
        };
        let mut own = ChaCha8Rng::seed_from_u64(seed ^ id.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        // A building that cannot be built is left out; the rest still render.
        let _ = scene.add_building(&outer, shape, true, &mut own);
    }
    scene.add_ground(lo, hi, reach + 20.0);
    let sun = Sun {
        azimuth_deg: rng.random_range(100.0..260.0),
        elevation_deg: rng.random_range(35.0..55.0),
        ambient: 0.25,
    };
    render(&scene.mesh, camera, &sun, &scene)
}

/// Camera and sensor effects on rendered imagery: colour balance, haze, blur, noise, JPEG.
fn develop(img: &mut Image, rng: &mut ChaCha8Rng) {
    let exposure = rng.random_range(0.75..1.3f32);
    let gains: [f32; 3] = std::array::from_fn(|_| rng.random_range(0.9..1.1f32));
    let haze = rng.random_range(0.0..0.1f32);
    let haze_colour = [0.55, 0.6, 0.7];
    for p in &mut img.pixels {
        for k in 0..3 {
            p[k] = (p[k] * exposure * gains[k]) * (1.0 - haze) + haze_colour[k] * haze;
        }
    }
    let sigma = rng.random_range(0.0..1.0f32);
    if sigma > 0.25 {
        gaussian_blur(img, sigma);
    }
    let grain = rng.random_range(0.0..0.025f32);
    let seed = rng.random::<u64>();
    for (i, p) in img.pixels.iter_mut().enumerate() {
        let n = (noise::hash01(i as i64, 0, seed) - 0.5) * 2.0 * grain;
        let bright = p.iter().sum::<f32>() / 3.0;
        // Noise in roughly perceptual units: larger in bright areas of linear light.
        let scale = 2.0 * bright.max(0.02).sqrt();
        for c in p.iter_mut() {
            *c = (*c + n * scale).max(0.0);
        }
    }
    if rng.random_bool(0.85) {
        jpeg_artefacts(img, rng.random_range(30..95u8));
    }
}

/// A separable Gaussian blur.
fn gaussian_blur(img: &mut Image, sigma: f32) {
    let r = (sigma * 2.5).ceil() as i64;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    let (w, h) = (img.width as i64, img.height as i64);
    for horizontal in [true, false] {
        let src = img.pixels.clone();
        for y in 0..h {
            for x in 0..w {
                let mut acc = [0.0f32; 3];
                for (k, &kv) in kernel.iter().enumerate() {
                    let d = k as i64 - r;
                    let (sx, sy) = if horizontal {
                        ((x + d).clamp(0, w - 1), y)
                    } else {
                        (x, (y + d).clamp(0, h - 1))
                    };
                    let s = src[(sy * w + sx) as usize];
                    for c in 0..3 {
                        acc[c] += s[c] * kv;
                    }
                }
                img.pixels[(y * w + x) as usize] = acc.map(|a| a / total);
            }
        }
    }
}

/// What every surface of a scene looks like.
#[derive(Debug, Clone)]
struct Look {
    palette: Palette,
    grass: [f32; 3],
    soil: [f32; 3],
    paving: [f32; 3],
    /// Roads: unit direction, offset of the centre line from the origin, half-width.
    roads: Vec<([f64; 2], f64, f64)>,
    ground_seed: u64,
}

/// The texture of a roof.
#[derive(Debug, Clone, Copy, PartialEq)]
enum RoofTexture {
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
struct RoofLook {
    colour: [f32; 3],
    texture: RoofTexture,
    contrast: f32,
    weathering: f32,
    seed: u64,
    /// Solar panels: the facing (unit downslope direction, or `None` on a flat roof) and a
    /// rectangle `[u0, u1, v0, v1]` in the footprint's axes around its centre.
    panels: Option<(Option<[f64; 2]>, [f64; 4])>,
    parapet: Option<(f64, [f32; 3])>,
    /// Brightness of ridges, hips and valleys against the roof.
    ridge: f32,
    outer: Vec<[f64; 2]>,
    centre: [f64; 2],
    axis: [f64; 2],
}

/// What a triangle of the scene is.
#[derive(Debug, Clone, Copy)]
enum Surface {
    Ground,
    Wall([f32; 3]),
    Roof(usize),
    Tree([f32; 3], u64),
    Solid([f32; 3]),
}

struct SceneBuilder {
    look: Look,
    mesh: Mesh,
    surfaces: Vec<Surface>,
    roofs: Vec<RoofLook>,
    frame: LocalFrame,
    elevation: ElevationModel,
}

fn linear(c: [u8; 3]) -> [f32; 3] {
    c.map(srgb8_to_linear)
}

/// A colour from the list, jittered in brightness and per channel.
fn pick(rng: &mut ChaCha8Rng, list: &[[u8; 3]]) -> [f32; 3] {
    let base = linear(list[rng.random_range(0..list.len())]);
    let bright = rng.random_range(0.75..1.25f32);
    base.map(|c| (c * bright * rng.random_range(0.9..1.1f32)).min(1.0))
}

const TRAIN_PITCHED: [[u8; 3]; 7] = [
    [168, 74, 52],
    [140, 62, 45],
    [120, 72, 55],
    [92, 90, 92],
    [58, 58, 64],
    [110, 58, 48],
    [150, 96, 70],
];
const TRAIN_FLAT: [[u8; 3]; 6] = [
    [170, 170, 168],
    [205, 205, 200],
    [140, 134, 124],
    [72, 72, 74],
    [118, 118, 112],
    [150, 140, 128],
];
const HOLDOUT_PITCHED: [[u8; 3]; 6] = [
    [190, 100, 66],
    [84, 92, 108],
    [138, 112, 92],
    [92, 134, 118],
    [40, 40, 42],
    [160, 60, 60],
];
const HOLDOUT_FLAT: [[u8; 3]; 6] = [
    [196, 186, 166],
    [96, 96, 100],
    [228, 228, 226],
    [150, 122, 104],
    [162, 166, 172],
    [60, 62, 58],
];
const WALLS: [[u8; 3]; 5] = [
    [220, 210, 190],
    [200, 180, 150],
    [170, 120, 100],
    [190, 190, 185],
    [230, 225, 215],
];

impl Look {
    fn draw(rng: &mut ChaCha8Rng, palette: Palette) -> Self {
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
    fn neighbour_shape(&self, rng: &mut ChaCha8Rng) -> RoofShape {
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

    fn roof(&self, rng: &mut ChaCha8Rng, shape: RoofShape, outer: &[[f64; 2]]) -> RoofLook {
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
        let rect = super::crop::min_rotated_rect(outer);
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

impl SceneBuilder {
    fn new(look: Look) -> Self {
        Self {
            look,
            mesh: Mesh::default(),
            surfaces: Vec::new(),
            roofs: Vec::new(),
            frame: LocalFrame::new(8.4, 49.0, 0.0),
            elevation: ElevationModel::default(),
        }
    }

    /// Builds one building with citymesh's generator; `None` when it cannot be built.
    fn add_building(
        &mut self,
        outer: &[[f64; 2]],
        shape: RoofShape,
        target: bool,
        rng: &mut ChaCha8Rng,
    ) -> Option<()> {
        let rect = super::crop::min_rotated_rect(outer)?;
        let flat = shape == RoofShape::Flat;
        let walls = if flat {
            rng.random_range(3.0..if target { 22.0 } else { 30.0 })
        } else {
            rng.random_range(3.0..13.0)
        };
        let pitch: f64 = rng.random_range(22.0..50.0f64).to_radians();
        let roof = match shape {
            RoofShape::Flat => 0.0,
            RoofShape::Skillion => rect.width * rng.random_range(0.05..0.25),
            _ => (rect.width / 2.0 * pitch.tan()).min(14.0),
        };
        let mut tags = Tags::default();
        tags.insert("building".into(), "yes".into());
        tags.insert("height".into(), format!("{:.2}", walls + roof));
        tags.insert("roof:shape".into(), shape.tag().into());
        if !flat {
            tags.insert("roof:height".into(), format!("{:.2}", roof));
        }
        if shape == RoofShape::Gabled && rng.random_bool(0.1) {
            tags.insert("roof:orientation".into(), "across".into());
        }
        let record = BuildingRecord {
            id: OsmId::Way(self.roofs.len() as i64 + 1),
            is_part: false,
            outers: vec![Ring {
                nodes: outer
                    .iter()
                    .map(|p| {
                        let (lon, lat, _) = self.frame.to_geographic([p[0], p[1], 0.0]);
                        RingNode { id: None, lon, lat }
                    })
                    .collect(),
            }],
            inners: Vec::new(),
            tags,
        };
        let ctx = BuildingContext {
            frame: &self.frame,
            elevation: &self.elevation,
            clip: None,
            heights: Default::default(),
            // The renders the classifier learnt from: kept as they were made.
            roof_method: crate::building::RoofMethod::Rectangle,
        };
        let mut part = Mesh::default();
        let mut stats = BuildingStats::default();
        generate_cluster(&[&record], &ctx, &mut part, &mut stats);
        if part.triangles.is_empty() {
            return None;
        }
        let roof_index = self.roofs.len();
        let look = self.look.roof(rng, shape, outer);
        let wall = pick(rng, &WALLS);
        let base = self.mesh.positions.len() as u32;
        self.mesh.positions.extend_from_slice(&part.positions);
        for (t, style) in part.triangles.iter().zip(&part.styles) {
            self.mesh.push_triangle(t.map(|i| i + base), *style);
            self.surfaces.push(match style.material {
                Material::Roof => Surface::Roof(roof_index),
                _ => Surface::Wall(wall),
            });
        }
        let centre = look.centre;
        let axis = look.axis;
        self.roofs.push(look);
        if target || rng.random_bool(0.5) {
            self.add_roof_clutter(&part, shape, centre, axis, rect.length, rect.width, rng);
        }
        Some(())
    }

    /// Chimneys and dormers on pitched roofs, roof units on flat ones: boxes standing on the roof.
    #[allow(clippy::too_many_arguments)]
    fn add_roof_clutter(
        &mut self,
        building: &Mesh,
        shape: RoofShape,
        centre: [f64; 2],
        axis: [f64; 2],
        length: f64,
        width: f64,
        rng: &mut ChaCha8Rng,
    ) {
        let flat = shape == RoofShape::Flat;
        let count = rng.random_range(0..if flat { 6 } else { 4 });
        for _ in 0..count {
            let u = rng.random_range(-0.4..0.4) * length;
            let v = rng.random_range(-0.35..0.35) * width;
            let at = [
                centre[0] + u * axis[0] - v * axis[1],
                centre[1] + u * axis[1] + v * axis[0],
            ];
            let Some(z) = roof_height_at(building, at) else {
                continue;
            };
            let (half, rise, colour) = if flat {
                (
                    [rng.random_range(0.4..1.6), rng.random_range(0.4..1.2)],
                    rng.random_range(0.6..1.8),
                    pick(rng, &[[190, 190, 188], [150, 150, 150], [220, 220, 215]]),
                )
            } else if rng.random_bool(0.5) {
                (
                    [rng.random_range(0.25..0.45), rng.random_range(0.25..0.45)],
                    rng.random_range(0.8..1.6),
                    pick(rng, &[[120, 60, 50], [90, 90, 90], [150, 140, 130]]),
                )
            } else {
                // A dormer: wider, lower, in the roof's colour family.
                (
                    [rng.random_range(0.6..1.2), rng.random_range(0.5..0.9)],
                    rng.random_range(0.5..1.0),
                    pick(rng, &[[150, 80, 60], [100, 100, 104], [200, 195, 185]]),
                )
            };
            add_box(
                &mut self.mesh,
                &mut self.surfaces,
                at,
                axis,
                half,
                z - 0.3,
                z + rise,
                Surface::Solid(colour),
            );
        }
    }

    /// Trees around the crop; some stand over the target and hide part of it.
    fn add_trees(&mut self, lo: [f64; 2], hi: [f64; 2], target: &[[f64; 2]], rng: &mut ChaCha8Rng) {
        let greens: &[[u8; 3]] = match self.look.palette {
            Palette::Training => &[[58, 86, 40], [44, 70, 36], [76, 98, 52]],
            Palette::Holdout => &[[70, 92, 50], [52, 66, 44], [96, 104, 60]],
        };
        // Trees stand beside buildings; now and then one reaches over the target's edge.
        let count = rng.random_range(0..6);
        for i in 0..count {
            let radius: f64 = rng.random_range(1.5..5.0);
            let over_edge = i == 0 && rng.random_bool(0.25);
            let mut placed = None;
            for _ in 0..20 {
                let at = if over_edge {
                    let p = target[rng.random_range(0..target.len())];
                    [
                        p[0] + rng.random_range(-2.0..2.0),
                        p[1] + rng.random_range(-2.0..2.0),
                    ]
                } else {
                    [
                        rng.random_range(lo[0]..hi[0]),
                        rng.random_range(lo[1]..hi[1]),
                    ]
                };
                let inside = crate::building::footprint::inside(target, at);
                let clear = distance_to_ring(target, at);
                if over_edge || (!inside && clear > 0.7 * radius) {
                    placed = Some(at);
                    break;
                }
            }
            let Some(at) = placed else {
                continue;
            };
            let radius = if over_edge { radius.min(3.0) } else { radius };
            let height = rng.random_range(4.0..14.0f64).max(radius * 1.5);
            let colour = pick(rng, greens);
            let seed = rng.random();
            add_tree(
                &mut self.mesh,
                &mut self.surfaces,
                at,
                radius,
                height,
                Surface::Tree(colour, seed),
                rng,
            );
        }
    }

    /// The ground: one large square around the crop.
    fn add_ground(&mut self, lo: [f64; 2], hi: [f64; 2], margin: f64) {
        let (x0, y0, x1, y1) = (
            lo[0] - margin,
            lo[1] - margin,
            hi[0] + margin,
            hi[1] + margin,
        );
        let style = FaceStyle::plain(Material::Ground, Rgb::GROUND);
        let i = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
            .map(|p| self.mesh.push_vertex([p[0], p[1], 0.0]));
        self.mesh.push_triangle([i[0], i[1], i[2]], style);
        self.mesh.push_triangle([i[0], i[2], i[3]], style);
        self.surfaces.extend([Surface::Ground, Surface::Ground]);
    }
}

/// The highest roof point of `building` above `at`, if a roof covers it.
fn roof_height_at(building: &Mesh, at: [f64; 2]) -> Option<f64> {
    let mut best: Option<f64> = None;
    for (t, style) in building.triangles.iter().zip(&building.styles) {
        if style.material != Material::Roof {
            continue;
        }
        let [a, b, c] = building.corners(*t);
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area.abs() < 1e-12 {
            continue;
        }
        let l1 = ((at[0] - a[0]) * (c[1] - a[1]) - (at[1] - a[1]) * (c[0] - a[0])) / area;
        let l2 = ((b[0] - a[0]) * (at[1] - a[1]) - (b[1] - a[1]) * (at[0] - a[0])) / area;
        let l0 = 1.0 - l1 - l2;
        if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
            continue;
        }
        let z = l0 * a[2] + l1 * b[2] + l2 * c[2];
        best = Some(best.map_or(z, |h: f64| h.max(z)));
    }
    best
}

/// A box around `at`, turned to `axis`, with half-sizes `half`, from `z0` to `z1`.
#[allow(clippy::too_many_arguments)]
fn add_box(
    mesh: &mut Mesh,
    surfaces: &mut Vec<Surface>,
    at: [f64; 2],
    axis: [f64; 2],
    half: [f64; 2],
    z0: f64,
    z1: f64,
    surface: Surface,
) {
    let corner = |su: f64, sv: f64| {
        let (u, v) = (su * half[0], sv * half[1]);
        [
            at[0] + u * axis[0] - v * axis[1],
            at[1] + u * axis[1] + v * axis[0],
        ]
    };
    let c = [
        corner(-1.0, -1.0),
        corner(1.0, -1.0),
        corner(1.0, 1.0),
        corner(-1.0, 1.0),
    ];
    let style = FaceStyle::plain(Material::Wall, Rgb(0, 0, 0));
    let mut quad = |q: [[f64; 3]; 4]| {
        let i = q.map(|p| mesh.push_vertex(p));
        mesh.push_triangle([i[0], i[1], i[2]], style);
        mesh.push_triangle([i[0], i[2], i[3]], style);
        surfaces.extend([surface, surface]);
    };
    quad(c.map(|p| [p[0], p[1], z1]));
    for k in 0..4 {
        let (a, b) = (c[k], c[(k + 1) % 4]);
        quad([
            [a[0], a[1], z0],
            [b[0], b[1], z0],
            [b[0], b[1], z1],
            [a[0], a[1], z1],
        ]);
    }
}

/// A tree crown: a lumpy dome of `radius` whose top is at `height`.
fn add_tree(
    mesh: &mut Mesh,
    surfaces: &mut Vec<Surface>,
    at: [f64; 2],
    radius: f64,
    height: f64,
    surface: Surface,
    rng: &mut ChaCha8Rng,
) {
    const SIDES: usize = 10;
    const RINGS: usize = 4;
    let style = FaceStyle::plain(Material::Wall, Rgb(0, 0, 0));
    let top = mesh.push_vertex([at[0], at[1], height]);
    let mut rings: Vec<Vec<u32>> = Vec::new();
    for r in 1..=RINGS {
        let polar = r as f64 / RINGS as f64 * std::f64::consts::FRAC_PI_2 * 1.15;
        let ring = (0..SIDES)
            .map(|s| {
                let az = s as f64 / SIDES as f64 * std::f64::consts::TAU;
                let lump = rng.random_range(0.8..1.15);
                let rr = radius * polar.sin() * lump;
                let z = height - radius * (1.0 - polar.cos()) * lump;
                mesh.push_vertex([at[0] + rr * az.cos(), at[1] + rr * az.sin(), z.max(0.5)])
            })
            .collect();
        rings.push(ring);
    }
    for s in 0..SIDES {
        let n = (s + 1) % SIDES;
        mesh.push_triangle([top, rings[0][s], rings[0][n]], style);
        surfaces.push(surface);
        for r in 1..RINGS {
            let (a, b) = (&rings[r - 1], &rings[r]);
            mesh.push_triangle([a[s], b[s], b[n]], style);
            mesh.push_triangle([a[s], b[n], a[n]], style);
            surfaces.extend([surface, surface]);
        }
    }
}

impl Albedo for SceneBuilder {
    fn albedo(&self, triangle: usize, p: [f64; 3], normal: [f64; 3]) -> [f32; 3] {
        match self.surfaces[triangle] {
            Surface::Ground => self.ground(p),
            Surface::Wall(c) | Surface::Solid(c) => c,
            Surface::Tree(c, seed) => {
                let n = noise::fractal(p[0] * 1.3, p[1] * 1.3, 3, seed);
                c.map(|v| v * (0.55 + 0.9 * n))
            }
            Surface::Roof(i) => self.roofs[i].albedo(p, normal),
        }
    }

    fn crease(&self, triangle: usize) -> Option<(u32, f32)> {
        match self.surfaces[triangle] {
            Surface::Roof(i) => Some((i as u32, self.roofs[i].ridge)),
            _ => None,
        }
    }
}

impl SceneBuilder {
    fn ground(&self, p: [f64; 3]) -> [f32; 3] {
        let look = &self.look;
        for (dir, offset, half) in &look.roads {
            let d = p[0] * -dir[1] + p[1] * dir[0] - offset;
            if d.abs() < *half {
                let n = noise::value(p[0] * 2.0, p[1] * 2.0, look.ground_seed);
                return look.paving.map(|c| c * (0.9 + 0.2 * n));
            }
        }
        let patches = noise::fractal(p[0] / 9.0, p[1] / 9.0, 3, look.ground_seed);
        let fine = noise::value(p[0] * 1.5, p[1] * 1.5, look.ground_seed ^ 7);
        let base = if patches > 0.62 {
            look.paving
        } else if patches < 0.3 {
            look.soil
        } else {
            look.grass
        };
        base.map(|c| c * (0.8 + 0.4 * fine))
    }
}

impl RoofLook {
    fn albedo(&self, p: [f64; 3], normal: [f64; 3]) -> [f32; 3] {
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

fn distance_to_ring(ring: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| crate::building::footprint::segment_distance(p, ring[i], ring[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min)
}

/// Twice the signed area (shoelace), halved.
fn ring_area(ring: &[[f64; 2]]) -> f64 {
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
fn overlaps(a: &[[f64; 2]], b: &[[f64; 2]]) -> bool {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_repeat_by_seed_and_cycle_through_the_classes() {
        let pool = FootprintPool::procedural(3);
        assert!(pool.targets().len() > 50, "{}", pool.targets().len());
        let rule = CropRule::MODEL;
        let a = render_sample(&pool, 12, Palette::Training, rule).expect("a sample");
        let b = render_sample(&pool, 12, Palette::Training, rule).expect("a sample");
        assert_eq!(a, b);
        assert_eq!(a.crop.rgb.len(), 96 * 96);
        let classes: Vec<RoofClass> = (30..36)
            .filter_map(|s| render_sample(&pool, s, Palette::Holdout, rule))
            .map(|s| s.class)
            .collect();
        assert_eq!(
            classes,
            [0, 1, 2, 0, 1, 2].map(|i| RoofClass::ALL[i]).to_vec()
        );
    }

    #[test]
    fn the_mask_covers_the_fill_share_of_the_crop_along_the_long_side() {
        // A lone 20 x 10 m building: with its mask known, the mask spans 80 % of the width.
        let pool = FootprintPool::new(vec![vec![
            [-10.0, -5.0],
            [10.0, -5.0],
            [10.0, 5.0],
            [-10.0, 5.0],
        ]]);
        let rule = CropRule::MODEL;
        let sample = (0..20)
            .filter_map(|s| render_sample(&pool, s, Palette::Training, rule))
            .find(|s| s.crop.mask.is_some())
            .expect("a sample with a mask");
        let mask = sample.crop.mask.expect("mask");
        let row: usize = (0..96).filter(|&x| mask[48 * 96 + x] == 255).count();
        let col: usize = (0..96).filter(|&y| mask[y * 96 + 48] == 255).count();
        // 20 m over 0.8 * 96 px: 76.8 px; 10 m: 38.4 px.
        assert!((76..=78).contains(&row), "{row}");
        assert!((38..=39).contains(&col), "{col}");
    }
}

#[cfg(test)]
mod shading_tests {
    use super::*;

    #[test]
    fn a_gabled_roof_shows_two_facets_under_a_sun_across_its_ridge() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let look = Look::draw(&mut rng, Palette::Training);
        let mut scene = SceneBuilder::new(look);
        let outer = [[-10.0, -5.0], [10.0, -5.0], [10.0, 5.0], [-10.0, 5.0]];
        scene
            .add_building(&outer, RoofShape::Gabled, false, &mut rng)
            .expect("built");
        scene.add_ground([-20.0, -20.0], [20.0, 20.0], 10.0);
        let zs: Vec<f64> = scene.mesh.positions.iter().map(|p| p[2]).collect();
        let top = zs.iter().copied().fold(f64::MIN, f64::max);
        eprintln!("top {top}");
        // A clean roof: no weathering, moss, panels or texture.
        scene.roofs[0].weathering = 0.0;
        scene.roofs[0].panels = None;
        scene.roofs[0].texture = RoofTexture::Plain;
        let camera = Camera {
            top_left: [-20.0, 20.0],
            metres_per_pixel: 0.25,
            width: 160,
            height: 160,
            skew: [0.0, 0.0],
        };
        let sun = Sun {
            azimuth_deg: 180.0,
            elevation_deg: 45.0,
            ambient: 0.35,
        };
        let img = render(&scene.mesh, &camera, &sun, &scene);
        let at = |x: f64, y: f64| {
            let p = camera.project([x, y, top]);
            img.get(p[0] as usize, p[1] as usize)
        };
        let (south, north) = (at(-3.0, -2.5), at(-3.0, 2.5));
        eprintln!("south {south:?} north {north:?}");
        assert!(south[0] > 1.5 * north[0], "{south:?} {north:?}");
    }
}

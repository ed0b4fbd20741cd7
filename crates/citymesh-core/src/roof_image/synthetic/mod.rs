//! Randomised training scenes for the roof classifier: one target building with a known roof class
//! among its real (or procedural) neighbours, built by citymesh's own generator, dressed with
//! roof materials and clutter (tile rows, gravel, membranes, metal seams, solar panels, chimneys,
//! dormers, roof units, parapets, weathering), trees as occluders, ground cover and roads, then
//! photographed like imagery: sun and sky, cast shadows, off-nadir skew, 0.1-0.5 m/px, footprint
//! misregistration, colour balance, haze, blur, noise and JPEG artefacts, and cropped by the crop
//! rule. Everything follows from the seed.

use super::class::RoofClass;
use super::crop::{Crop, CropFrame, CropRule};
use super::image::Image;
use super::render::{Camera, Sun, render};
use crate::building::roof::RoofShape;
use crate::geo::LocalFrame;
use crate::osm::{BuildingRecord, OsmId};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod develop;
mod footprints;
mod looks;
mod scene_builder;
mod trees;

use develop::develop;
pub use footprints::FootprintPool;
use footprints::overlaps;
use looks::Look;
use scene_builder::SceneBuilder;

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

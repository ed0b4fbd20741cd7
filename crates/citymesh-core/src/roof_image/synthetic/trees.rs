//! Trees as occluders: around the crop, some over the target.

use super::Palette;
use super::looks::{distance_to_ring, pick};
use super::scene_builder::{SceneBuilder, Surface};
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

impl SceneBuilder {
    /// Trees around the crop; some stand over the target and hide part of it.
    pub(super) fn add_trees(
        &mut self,
        lo: [f64; 2],
        hi: [f64; 2],
        target: &[[f64; 2]],
        rng: &mut ChaCha8Rng,
    ) {
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
}

/// A tree crown: a lumpy dome of `radius` whose top is at `height`.
pub(super) fn add_tree(
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

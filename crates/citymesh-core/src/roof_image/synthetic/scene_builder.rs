//! Laying out a training scene: the target and its neighbours built by citymesh's generator,
//! roof clutter and the ground, with what each triangle is for the renderer.

use super::looks::{Look, RoofLook, WALLS, pick};
use crate::building::roof::RoofShape;
use crate::building::{BuildingContext, BuildingStats, generate_cluster};
use crate::geo::LocalFrame;
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};
use crate::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use crate::roof_image::noise;
use crate::roof_image::render::Albedo;
use crate::terrain::ElevationModel;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// What a triangle of the scene is.
#[derive(Debug, Clone, Copy)]
pub(super) enum Surface {
    Ground,
    Wall([f32; 3]),
    Roof(usize),
    Tree([f32; 3], u64),
    Solid([f32; 3]),
}

pub(super) struct SceneBuilder {
    pub(super) look: Look,
    pub(super) mesh: Mesh,
    pub(super) surfaces: Vec<Surface>,
    pub(super) roofs: Vec<RoofLook>,
    pub(super) frame: LocalFrame,
    pub(super) elevation: ElevationModel,
}

impl SceneBuilder {
    pub(super) fn new(look: Look) -> Self {
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
    pub(super) fn add_building(
        &mut self,
        outer: &[[f64; 2]],
        shape: RoofShape,
        target: bool,
        rng: &mut ChaCha8Rng,
    ) -> Option<()> {
        let rect = crate::roof_image::crop::min_rotated_rect(outer)?;
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
            tags: Default::default(),
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
    pub(super) fn add_roof_clutter(
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
}

impl SceneBuilder {
    /// The ground: one large square around the crop.
    pub(super) fn add_ground(&mut self, lo: [f64; 2], hi: [f64; 2], margin: f64) {
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
pub(super) fn roof_height_at(building: &Mesh, at: [f64; 2]) -> Option<f64> {
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
pub(super) fn add_box(
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
    pub(super) fn ground(&self, p: [f64; 3]) -> [f32; 3] {
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

#[cfg(test)]
mod shading_tests {
    use super::*;
    use crate::roof_image::render::{Camera, Sun, render};
    use crate::roof_image::synthetic::Palette;
    use crate::roof_image::synthetic::looks::RoofTexture;
    use rand::SeedableRng;

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

//! Every roof shape on a 20 m x 8 m rectangle, axis-aligned and rotated: every roof vertex
//! has the height the descending level functions of docs/method.md section 6 give (written out here
//! independently of the generator), the shapes' characteristic points are there, and the limit
//! cases equal the shapes they reduce to, vertex for vertex.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use citymesh_core::building::axes::RoofAxes;
use citymesh_core::building::footprint::{Footprint, FootprintRing};
use citymesh_core::building::group::{Volume, mesh_group};
use citymesh_core::building::roof::RoofShape;
use citymesh_core::building::roof_surface::RoofSurface;
use citymesh_core::building::tags::Orientation;
use citymesh_core::geo::{GeoBbox, LocalFrame};
use citymesh_core::mesh::{Material, Mesh, Rgb, check_closed};
use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;
use rstest::rstest;

const RX: f64 = 10.0;
const RY: f64 = 4.0;
const TOP: f64 = 12.0;
const ROOF: f64 = 4.0;
/// The default HE, GP and MP.
const P: f64 = 0.7;

/// The rectangle's centre (metres in the scene frame) and its long axis at `angle` degrees.
struct Rect {
    centre: [f64; 2],
    u: [f64; 2],
    v: [f64; 2],
}

impl Rect {
    fn new(angle: f64) -> Self {
        let (s, c) = angle.to_radians().sin_cos();
        Rect {
            centre: [3.0, -2.0],
            u: [c, s],
            v: [-s, c],
        }
    }
    fn point(&self, x: f64, y: f64) -> [f64; 2] {
        [
            self.centre[0] + x * RX * self.u[0] + y * RY * self.v[0],
            self.centre[1] + x * RX * self.u[1] + y * RY * self.v[1],
        ]
    }
    /// (x', y') of a point, x' along the long side.
    fn alt(&self, p: [f64; 2]) -> [f64; 2] {
        let d = [p[0] - self.centre[0], p[1] - self.centre[1]];
        [
            (d[0] * self.u[0] + d[1] * self.u[1]) / RX,
            (d[0] * self.v[0] + d[1] * self.v[1]) / RY,
        ]
    }
    fn corners(&self) -> Vec<[f64; 2]> {
        vec![
            self.point(-1.0, -1.0),
            self.point(1.0, -1.0),
            self.point(1.0, 1.0),
            self.point(-1.0, 1.0),
        ]
    }
}

/// g(t) of the gambrel and mansard profiles.
fn g(p: f64, t: f64) -> f64 {
    if t <= p {
        (1.0 - p) / p * t
    } else {
        1.0 - p / (1.0 - p) * (1.0 - t)
    }
}

/// Linear between the points of a profile (t, DLF) rising from (0, 0) to (1, 1); 1 beyond.
fn along(profile: &[(f64, f64)], t: f64) -> f64 {
    for w in profile.windows(2) {
        let ((t0, d0), (t1, d1)) = (w[0], w[1]);
        if t <= t1 {
            return d0 + (d1 - d0) * (t - t0) / (t1 - t0);
        }
    }
    1.0
}

/// A half circle sampled at sin(k pi / 12): (t, 1 - sqrt(1 - t^2)).
fn half_circle() -> Vec<(f64, f64)> {
    (0..=6)
        .map(|k| {
            let a = f64::from(k) * std::f64::consts::PI / 12.0;
            (a.sin(), 1.0 - a.cos())
        })
        .collect()
}

/// The radius of the 16-sided polygon inscribed in the unit circle (a vertex on +x') through
/// (x', y'): the largest projection on its sides' normals.
fn polygon_radius(x: f64, y: f64) -> f64 {
    let half = std::f64::consts::PI / 16.0;
    (0..16)
        .map(|j| {
            let m = (2.0 * f64::from(j) + 1.0) * half;
            (x * m.cos() + y * m.sin()) / half.cos()
        })
        .fold(f64::MIN, f64::max)
}

/// The DLF of docs/method.md section 6 at (x', y') for the defaults (HE = GP = MP = 0.7).
fn expected_dlf(shape: RoofShape, [x, y]: [f64; 2]) -> f64 {
    let x_h = 1.0 - RY / RX;
    match shape {
        // The ridge a quarter of the width from +y'.
        RoofShape::Saltbox => {
            if y >= 0.5 {
                (y - 0.5) / 0.5
            } else {
                (0.5 - y) / 1.5
            }
        }
        // Gambrel and mansard profiles with their kink at 0.3: steep above, shallow below.
        RoofShape::DoubleSaltbox => g(0.3, y.abs()),
        RoofShape::QuadrupleSaltbox => {
            let dx = if x.abs() <= x_h {
                0.0
            } else {
                g(0.3, (x.abs() - x_h) / (1.0 - x_h))
            };
            dx.max(g(0.3, y.abs()))
        }
        RoofShape::SideHipped => {
            let dx = if x <= x_h {
                0.0
            } else {
                (x - x_h) / (1.0 - x_h)
            };
            dx.max(y.abs())
        }
        RoofShape::SideHalfHipped => {
            let x_hh = 1.0 - (1.0 - P) * RY / RX;
            let dx = if x <= x_hh { 0.0 } else { (x - x_hh) * RX / RY };
            dx.max(y.abs())
        }
        // 8 m across: two teeth, each rising over 0.9 of its width.
        RoofShape::Sawtooth => {
            let t = if y < 0.0 { y + 1.0 } else { y };
            if t <= 0.9 {
                1.0 - t / 0.9
            } else {
                (t - 0.9) / 0.1
            }
        }
        RoofShape::Crosspitched => x.abs().min(y.abs()),
        RoofShape::Round => along(&half_circle(), y.abs()),
        RoofShape::Dome => along(&half_circle(), polygon_radius(x, y)),
        RoofShape::Onion => along(
            &[
                (0.0, 0.0),
                (0.08, 0.06),
                (0.2, 0.16),
                (0.4, 0.3),
                (0.6, 0.42),
                (0.8, 0.56),
                (0.93, 0.72),
                (1.0, 1.0),
            ],
            polygon_radius(x, y),
        ),
        RoofShape::Cone => polygon_radius(x, y).min(1.0),
        RoofShape::Frustum => ((x.abs().max(y.abs()) - 0.5) / 0.5).max(0.0),
        RoofShape::Flat => 0.0,
        RoofShape::Gabled => y.abs(),
        RoofShape::Hipped => {
            let dx = if x.abs() <= x_h {
                0.0
            } else {
                (x.abs() - x_h) / (1.0 - x_h)
            };
            dx.max(y.abs())
        }
        RoofShape::Pyramidal => x.abs().max(y.abs()),
        // Tested with roof:direction along -y' (see `record`): the roof falls towards -y'.
        RoofShape::Skillion => (-y + 1.0) / 2.0,
        RoofShape::HalfHipped => {
            let y_h = 1.0 - P;
            let x_hh = 1.0 - y_h * RY / RX;
            let dx = if x.abs() <= x_hh {
                0.0
            } else {
                (x.abs() - x_hh) * RX / RY
            };
            dx.max(y.abs())
        }
        RoofShape::Gambrel => g(P, y.abs()),
        RoofShape::Mansard => {
            let dx = if x.abs() <= x_h {
                0.0
            } else {
                g(P, (x.abs() - x_h) / (1.0 - x_h))
            };
            dx.max(g(P, y.abs()))
        }
    }
}

/// Points every roof of the shape must have as vertices, in (x', y').
fn characteristic_points(shape: RoofShape) -> Vec<[f64; 2]> {
    let x_h = 1.0 - RY / RX;
    let corners = vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let extra: Vec<[f64; 2]> = match shape {
        RoofShape::Flat | RoofShape::Skillion => vec![],
        RoofShape::Saltbox => vec![[-1.0, 0.5], [1.0, 0.5]],
        RoofShape::DoubleSaltbox => vec![[-1.0, 0.0], [1.0, 0.0], [1.0, 0.3], [-1.0, -0.3]],
        RoofShape::QuadrupleSaltbox => {
            let x_m = x_h + 0.3 * (1.0 - x_h);
            vec![[-x_h, 0.0], [x_h, 0.0], [x_m, 0.3], [-x_m, -0.3]]
        }
        RoofShape::SideHipped => vec![[-1.0, 0.0], [x_h, 0.0]],
        RoofShape::SideHalfHipped => {
            let x_hh = 1.0 - (1.0 - P) * RY / RX;
            vec![[-1.0, 0.0], [x_hh, 0.0], [1.0, 1.0 - P], [1.0, P - 1.0]]
        }
        RoofShape::Sawtooth => vec![[-1.0, -0.1], [1.0, -0.1], [-1.0, 0.0], [1.0, 0.9]],
        RoofShape::Crosspitched => vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]],
        RoofShape::Round => vec![[-1.0, 0.0], [1.0, 0.0]],
        RoofShape::Dome | RoofShape::Onion | RoofShape::Cone => {
            vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
        }
        RoofShape::Frustum => vec![[0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5], [0.5, -0.5]],
        RoofShape::Gabled => vec![[-1.0, 0.0], [1.0, 0.0]],
        RoofShape::Hipped => vec![[-x_h, 0.0], [x_h, 0.0]],
        RoofShape::Pyramidal => vec![[0.0, 0.0]],
        RoofShape::HalfHipped => {
            let y_h = 1.0 - P;
            let x_hh = 1.0 - y_h * RY / RX;
            vec![
                [-x_hh, 0.0],
                [x_hh, 0.0],
                [1.0, y_h],
                [1.0, -y_h],
                [-1.0, y_h],
                [-1.0, -y_h],
            ]
        }
        RoofShape::Gambrel => vec![
            [-1.0, 0.0],
            [1.0, 0.0],
            [1.0, P],
            [1.0, -P],
            [-1.0, P],
            [-1.0, -P],
        ],
        RoofShape::Mansard => {
            let x_m = x_h + P * (1.0 - x_h);
            vec![
                [-x_h, 0.0],
                [x_h, 0.0],
                [x_m, P],
                [x_m, -P],
                [-x_m, P],
                [-x_m, -P],
            ]
        }
    };
    corners.into_iter().chain(extra).collect()
}

/// A building record of the rectangle, placed so the scene frame is the test's frame.
fn record(rect: &Rect, frame: &LocalFrame, shape: RoofShape) -> BuildingRecord {
    let nodes = rect
        .corners()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (lon, lat, _) = frame.to_geographic([p[0], p[1], 0.0]);
            RingNode {
                id: Some(i as i64 + 1),
                lon,
                lat,
            }
        })
        .collect();
    // The skillion falls towards -y' (the compass direction of -v).
    let direction = (-rect.v[0])
        .atan2(-rect.v[1])
        .to_degrees()
        .rem_euclid(360.0);
    let tags = [
        ("building", "house".to_owned()),
        ("height", TOP.to_string()),
        ("roof:height", ROOF.to_string()),
        ("roof:shape", shape.tag().to_owned()),
        ("roof:direction", format!("{direction}")),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_owned(), v))
    .collect();
    BuildingRecord {
        id: OsmId::Way(1),
        is_part: false,
        outers: vec![Ring { nodes }],
        inners: vec![],
        tags,
    }
}

/// The scene of one building on flat ground at 0 m, in a frame at about (8.4, 49.0).
fn scene(rect: &Rect, shape: RoofShape) -> (Scene, LocalFrame) {
    let bbox = GeoBbox::new(8.399, 48.999, 8.401, 49.001).unwrap();
    let (lon, lat) = bbox.center();
    let frame = LocalFrame::new(lon, lat, 0.0);
    let rec = record(rect, &frame, shape);
    let scene = Scene::new(
        &ElevationModel::default(),
        &bbox,
        &[vec![&rec]],
        Border::Whole,
    );
    assert_eq!(scene.frame, frame);
    (scene, frame)
}

fn roof_vertices(mesh: &Mesh) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::new();
    for (t, s) in mesh.triangles.iter().zip(&mesh.styles) {
        if s.material == Material::Roof {
            for p in mesh.corners(*t) {
                if !out.contains(&p) {
                    out.push(p);
                }
            }
        }
    }
    out
}

#[rstest]
fn every_roof_vertex_has_the_dlf_height(
    #[values(
        RoofShape::Flat,
        RoofShape::Gabled,
        RoofShape::Hipped,
        RoofShape::Pyramidal,
        RoofShape::Skillion,
        RoofShape::HalfHipped,
        RoofShape::Gambrel,
        RoofShape::Mansard,
        RoofShape::Saltbox,
        RoofShape::DoubleSaltbox,
        RoofShape::QuadrupleSaltbox,
        RoofShape::SideHipped,
        RoofShape::SideHalfHipped,
        RoofShape::Sawtooth,
        RoofShape::Crosspitched,
        RoofShape::Round,
        RoofShape::Dome,
        RoofShape::Onion,
        RoofShape::Cone,
        RoofShape::Frustum
    )]
    shape: RoofShape,
    #[values(0.0, 30.0, -117.0)] angle: f64,
) {
    let rect = Rect::new(angle);
    let (scene, _) = scene(&rect, shape);
    let roof = roof_vertices(&scene.mesh);
    assert!(!roof.is_empty());
    let roof_height = if shape == RoofShape::Flat { 0.0 } else { ROOF };
    // roof:direction points to -y' (see `record`): the saltbox's and the sawtooth's long slopes
    // face it, as written in `expected_dlf`. It is square to the axis that decides which end of
    // a side-hipped roof is hipped, so that one may stand either way round: the whole roof
    // turned by 180 degrees, the same for every vertex.
    let turned = |[x, y]: [f64; 2]| [-x, -y];
    let fits = |flip: bool| {
        roof.iter().all(|p| {
            let a = rect.alt([p[0], p[1]]);
            let a = if flip { turned(a) } else { a };
            (p[2] - (TOP - roof_height * expected_dlf(shape, a))).abs() < 1e-6
        })
    };
    let either_way = matches!(shape, RoofShape::SideHipped | RoofShape::SideHalfHipped);
    let flip = either_way && !fits(false) && fits(true);
    let rect_alt = |p: [f64; 2]| {
        let a = rect.alt(p);
        if flip { turned(a) } else { a }
    };
    for p in &roof {
        let a = rect_alt([p[0], p[1]]);
        let expected = TOP - roof_height * expected_dlf(shape, a);
        assert!(
            (p[2] - expected).abs() < 1e-6,
            "{shape:?} at {angle} deg: vertex {a:?} is at {}, expected {expected}",
            p[2]
        );
    }
    for q in characteristic_points(shape) {
        assert!(
            roof.iter().any(|p| {
                let a = rect_alt([p[0], p[1]]);
                (a[0] - q[0]).abs() < 1e-6 && (a[1] - q[1]).abs() < 1e-6
            }),
            "{shape:?} at {angle} deg lacks a vertex at {q:?}"
        );
    }
    let report = check_closed(&scene.mesh, scene.cluster_triangles[0].clone());
    assert!(report.is_closed_and_outward(), "{report:?}");
}

#[test]
fn across_turns_the_ridge_of_a_gable() {
    let rect = Rect::new(30.0);
    let bbox = GeoBbox::new(8.399, 48.999, 8.401, 49.001).unwrap();
    let (lon, lat) = bbox.center();
    let frame = LocalFrame::new(lon, lat, 0.0);
    let mut rec = record(&rect, &frame, RoofShape::Gabled);
    rec.tags
        .insert("roof:orientation".to_owned(), "across".to_owned());
    let scene = Scene::new(
        &ElevationModel::default(),
        &bbox,
        &[vec![&rec]],
        Border::Whole,
    );
    // The ridge now runs along y' at x' = 0; the roof falls over RX to the short walls.
    for p in roof_vertices(&scene.mesh) {
        let [x, _] = rect.alt([p[0], p[1]]);
        assert!((p[2] - (TOP - ROOF * x.abs())).abs() < 1e-6);
    }
}

/// The roof vertices (x', y', height) of a shape with an explicit parameter, sorted.
fn roof_with(shape: RoofShape, parameter: Option<f64>) -> Vec<[i64; 3]> {
    let rect = Rect::new(30.0);
    let ring = FootprintRing::from_points(rect.corners());
    let footprint = Footprint::new(ring, vec![]).unwrap();
    let axes = RoofAxes::of_ring(&footprint.outer.points)
        .unwrap()
        .long_first();
    let roof = RoofSurface::new(
        shape,
        axes,
        Orientation::Along,
        &footprint.outer.points,
        None,
        parameter,
    )
    .with_heights(TOP, ROOF);
    let volume = Volume {
        footprint: std::borrow::Cow::Owned(footprint),
        roof: 0,
        floor: 0.0,
        wall_colour: Rgb(0, 0, 0),
        roof_colour: Rgb(0, 0, 0),
        feature: 0,
    };
    let mut mesh = Mesh::default();
    mesh_group(&[volume], &[roof], &mut mesh);
    let mut v: Vec<[i64; 3]> = roof_vertices(&mesh)
        .into_iter()
        .map(|p| {
            let a = rect.alt([p[0], p[1]]);
            [a[0], a[1], p[2]].map(|c| (c * 1e6).round() as i64)
        })
        .collect();
    v.sort();
    v
}

#[rstest]
#[case(RoofShape::HalfHipped, 0.0, RoofShape::Hipped)]
#[case(RoofShape::HalfHipped, 1.0, RoofShape::Gabled)]
#[case(RoofShape::Gambrel, 0.5, RoofShape::Gabled)]
#[case(RoofShape::Gambrel, 1.0, RoofShape::Flat)]
#[case(RoofShape::Mansard, 0.5, RoofShape::Hipped)]
#[case(RoofShape::Mansard, 1.0, RoofShape::Flat)]
fn limit_cases_equal_their_shapes_vertex_for_vertex(
    #[case] shape: RoofShape,
    #[case] parameter: f64,
    #[case] equals: RoofShape,
) {
    // A flat roof has no roof height and stands at the top, where the limits of the pitched
    // shapes end up too.
    assert_eq!(roof_with(shape, Some(parameter)), roof_with(equals, None));
}

//! The roof of one building as a height function over the plane: the virtual rectangle of the
//! footprint (turned for `roof:orientation`, or along `roof:direction` for skillions) and a roof
//! model's descending level function, or the footprint's straight skeleton
//! ([`super::skeleton_roof`]); and the heights of eaves and top (docs/method.md sections 4-6.7).
use super::length::planar_length;

use super::axes::RoofAxes;
use super::roof::{
    Alt, FRUSTUM_TOP, RoofModel, RoofShape, SALTBOX_RIDGE, SAWTOOTH_RISE, Sawtooth, model,
};
use super::skeleton_roof::SkeletonRoof;
use super::tags::Orientation;

/// What the descending level function is laid over.
enum Plan {
    /// The virtual rectangle, in alternative coordinates.
    Rectangle(Box<dyn RoofModel + Send + Sync>),
    /// The footprint's straight skeleton, in metres.
    Skeleton(SkeletonRoof),
}

/// A roof: `height(p) = top - roof_height * DLF(p)`, the DLF taken over the virtual rectangle
/// (`DLF(x'(p), y'(p))`) or the straight skeleton.
pub struct RoofSurface {
    pub shape: RoofShape,
    /// The alternative coordinates: `a = x'` runs along the ridge, `b = y'` across it.
    pub axes: RoofAxes,
    plan: Plan,
    /// Height of the top (ridge), metres in the local frame.
    pub top: f64,
    /// Height of the roof from eaves to top, metres (0 for flat roofs).
    pub roof_height: f64,
}

impl RoofSurface {
    /// The roof over a footprint whose axes were found from its whole outline. `axes` must already
    /// put the longer side first ([`RoofAxes::long_first`]); `direction` is `roof:direction` in
    /// degrees from north: where a skillion descends, and which way the shapes with one distinct
    /// side face ([`facing`]); `parameter` is HE, GP or MP when known.
    pub fn new(
        shape: RoofShape,
        axes: RoofAxes,
        orientation: Orientation,
        outer: &[[f64; 2]],
        direction: Option<f64>,
        parameter: Option<f64>,
    ) -> Self {
        let axes = match shape {
            RoofShape::Skillion => {
                // The roof descends towards `roof:direction`; without one, across the long side.
                let dir = direction.map_or([-axes.m[0], -axes.m[1]], |d| {
                    let r = d.to_radians();
                    [r.sin(), r.cos()]
                });
                RoofAxes::along(outer, dir).unwrap_or(axes)
            }
            _ if orientation == Orientation::Across => swap(axes),
            _ => axes,
        };
        let axes = match direction {
            Some(d) => facing(shape, axes, d),
            None => axes,
        };
        Self {
            shape,
            plan: Plan::Rectangle(model(shape, axes.rx, axes.ry, parameter)),
            axes,
            top: 0.0,
            roof_height: 0.0,
        }
    }

    /// A `shape` roof over a footprint's straight skeleton (`axes`: its virtual rectangle, kept
    /// for what asks for it).
    pub fn over_skeleton(shape: RoofShape, axes: RoofAxes, roof: SkeletonRoof) -> Self {
        Self {
            shape,
            plan: Plan::Skeleton(roof),
            axes,
            top: 0.0,
            roof_height: 0.0,
        }
    }

    /// Whether the roof is laid over the straight skeleton.
    pub fn is_skeleton(&self) -> bool {
        matches!(self.plan, Plan::Skeleton(_))
    }

    /// Sets the heights: the top of the roof and the roof's own height (eaves to top).
    pub fn with_heights(mut self, top: f64, roof_height: f64) -> Self {
        self.top = top;
        self.roof_height = if self.shape == RoofShape::Flat {
            0.0
        } else {
            roof_height
        };
        self
    }

    /// The distance in metres a slope of `angle_degrees` needs to rise by `h` over this roof: the
    /// horizontal run from eaves to top.
    pub fn run(&self) -> f64 {
        if let Plan::Skeleton(roof) = &self.plan {
            return if self.shape == RoofShape::Flat {
                0.0
            } else {
                roof.run()
            };
        }
        let (rx, ry) = (self.axes.rx, self.axes.ry);
        match self.shape {
            RoofShape::Flat => 0.0,
            // A skillion rises over the whole length of its slope axis.
            RoofShape::Skillion => 2.0 * rx,
            RoofShape::Pyramidal | RoofShape::Crosspitched => rx.min(ry),
            // Shapes of revolution rise from the inscribed ellipse's narrow side.
            RoofShape::Dome | RoofShape::Onion | RoofShape::Cone => rx.min(ry),
            RoofShape::Frustum => (1.0 - FRUSTUM_TOP) * rx.min(ry),
            // The longer slope, from the far side to the ridge.
            RoofShape::Saltbox => (1.0 + SALTBOX_RIDGE) * ry,
            RoofShape::Sawtooth => SAWTOOTH_RISE * 2.0 * ry / Sawtooth::teeth(ry) as f64,
            _ => ry,
        }
    }

    /// The descending level function at a point in metres.
    #[inline]
    pub fn dlf(&self, p: [f64; 2]) -> f64 {
        match &self.plan {
            Plan::Rectangle(model) => model.dlf(self.axes.to_alt(p)),
            Plan::Skeleton(roof) => roof.dlf(p),
        }
    }

    /// The roof height at a point in metres.
    #[inline]
    pub fn height_at(&self, p: [f64; 2]) -> f64 {
        if self.roof_height == 0.0 {
            return self.top;
        }
        self.top - self.roof_height * self.dlf(p)
    }

    /// Whether the roof is one plane (so it needs no dividing segments).
    pub fn is_planar(&self) -> bool {
        self.roof_height == 0.0 || matches!(self.shape, RoofShape::Flat | RoofShape::Skillion)
    }

    /// The dividing segments of the shape in metres: the edges between virtual faces, where the
    /// roof bends (docs/method.md section 5).
    pub fn dividing_segments(&self) -> Vec<[[f64; 2]; 2]> {
        if self.is_planar() {
            return Vec::new();
        }
        let model = match &self.plan {
            Plan::Rectangle(model) => model,
            Plan::Skeleton(roof) => return roof.dividing_segments(),
        };
        let mut segments: Vec<[Alt; 2]> = Vec::new();
        for face in model.faces() {
            let n = face.len();
            for i in 0..n {
                let (p, q) = (face[i], face[(i + 1) % n]);
                if on_same_square_side(p, q) {
                    continue;
                }
                let key = if (p[0], p[1]) < (q[0], q[1]) {
                    [p, q]
                } else {
                    [q, p]
                };
                if !segments.contains(&key) {
                    segments.push(key);
                }
            }
        }
        // Only where the roof really bends: limit parameters (gambrel GP = 0.5, a flat mansard)
        // leave segments across which the roof is one plane.
        segments.retain(|&[p, q]| self.bends_across(p, q));
        join_collinear(&mut segments);
        segments
            .into_iter()
            .map(|[p, q]| [self.axes.from_alt(p), self.axes.from_alt(q)])
            .collect()
    }

    /// Whether the DLF has a kink across the segment `p`-`q` (alternative coordinates).
    fn bends_across(&self, p: Alt, q: Alt) -> bool {
        let m = [(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0];
        let d = [q[0] - p[0], q[1] - p[1]];
        let len = planar_length(d[0], d[1]);
        let e = 1e-4;
        let n = [-d[1] / len * e, d[0] / len * e];
        let Plan::Rectangle(model) = &self.plan else {
            return true;
        };
        let f = |a: Alt| model.dlf(a);
        let (l, c, r) = (
            f([m[0] + n[0], m[1] + n[1]]),
            f(m),
            f([m[0] - n[0], m[1] - n[1]]),
        );
        (l + r - 2.0 * c).abs() > 1e-9
    }
}

/// Joins segments that continue each other in a straight line through a point no other segment
/// touches, so a limit shape has the very same vertices as the shape it equals.
fn join_collinear(segments: &mut Vec<[Alt; 2]>) {
    loop {
        let mut joined = false;
        'outer: for i in 0..segments.len() {
            for j in i + 1..segments.len() {
                let (a, b) = (segments[i], segments[j]);
                for (shared, x, y) in [
                    (a[0], a[1], if b[0] == a[0] { b[1] } else { b[0] }),
                    (a[1], a[0], if b[0] == a[1] { b[1] } else { b[0] }),
                ] {
                    if b[0] != shared && b[1] != shared {
                        continue;
                    }
                    let degree = segments
                        .iter()
                        .filter(|s| s[0] == shared || s[1] == shared)
                        .count();
                    let cross =
                        (shared[0] - x[0]) * (y[1] - x[1]) - (shared[1] - x[1]) * (y[0] - x[0]);
                    if degree == 2 && cross.abs() < 1e-12 {
                        segments[i] = [x, y];
                        segments.swap_remove(j);
                        joined = true;
                        break 'outer;
                    }
                }
            }
        }
        if !joined {
            return;
        }
    }
}

/// The same rectangle with the roles of x' and y' exchanged (`roof:orientation=across`).
/// The axes turned so that a shape with one distinct side faces `roof:direction` (`degrees`
/// from north), the rectangle unchanged: a saltbox's long slope and a sawtooth's long slopes
/// descend towards it; a side-hipped or side-half-hipped roof has its hipped end there. Other
/// shapes, and a direction square to the axis that decides, keep their axes.
fn facing(shape: RoofShape, a: RoofAxes, degrees: f64) -> RoofAxes {
    let r = degrees.to_radians();
    let dir = [r.sin(), r.cos()];
    let along = |v: [f64; 2]| v[0] * dir[0] + v[1] * dir[1];
    match shape {
        // Their long slopes descend towards -b.
        RoofShape::Saltbox | RoofShape::Sawtooth if along(a.m) > 1e-9 => RoofAxes {
            m: [-a.m[0], -a.m[1]],
            y0: -a.y0,
            ..a
        },
        // The hip is at +a.
        RoofShape::SideHipped | RoofShape::SideHalfHipped if along(a.n) < -1e-9 => RoofAxes {
            n: [-a.n[0], -a.n[1]],
            x0: -a.x0,
            ..a
        },
        _ => a,
    }
}

fn swap(a: RoofAxes) -> RoofAxes {
    RoofAxes {
        n: a.m,
        m: a.n,
        x0: a.y0,
        rx: a.ry,
        y0: a.x0,
        ry: a.rx,
    }
}

/// Whether an edge of a virtual face lies on the border of the square [-1, 1]².
fn on_same_square_side(p: Alt, q: Alt) -> bool {
    (0..2).any(|k| (p[k] == q[k]) && p[k].abs() == 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rectangle() -> (Vec<[f64; 2]>, RoofAxes) {
        let ring = vec![[0.0, 0.0], [20.0, 0.0], [20.0, 8.0], [0.0, 8.0]];
        let axes = RoofAxes::of_ring(&ring).unwrap().long_first();
        (ring, axes)
    }

    #[test]
    fn one_sided_shapes_face_the_roof_direction() {
        // 20 m along x (east), 8 m along y (north).
        let (ring, axes) = rectangle();
        let roof = |shape, direction: f64| {
            RoofSurface::new(
                shape,
                axes,
                Orientation::Along,
                &ring,
                Some(direction),
                None,
            )
            .with_heights(10.0, 4.0)
        };
        for (direction, long_side, short_side) in [
            (180.0, [10.0, 0.0], [10.0, 8.0]),
            (0.0, [10.0, 8.0], [10.0, 0.0]),
        ] {
            // The saltbox's ridge stands a quarter of the width from the side away from
            // `roof:direction`: 2 m from it, 6 m from the other.
            let saltbox = roof(RoofShape::Saltbox, direction);
            let ridge_y = if direction == 0.0 { 2.0 } else { 6.0 };
            assert!(
                (saltbox.height_at([10.0, ridge_y]) - 10.0).abs() < 1e-9,
                "{direction}"
            );
            assert!((saltbox.height_at(long_side) - 6.0).abs() < 1e-9);
            assert!((saltbox.height_at(short_side) - 6.0).abs() < 1e-9);
            // A quarter of the way down the long slope is a quarter of the roof lower.
            let quarter = [10.0, ridge_y + (long_side[1] - ridge_y) / 4.0];
            assert!((saltbox.height_at(quarter) - 9.0).abs() < 1e-9);
            // Each sawtooth's long slope descends towards `roof:direction`: two teeth 4 m wide,
            // their tops 0.4 m from their steep faces.
            let saw = roof(RoofShape::Sawtooth, direction);
            let top_y = if direction == 0.0 { 0.4 } else { 3.6 };
            assert!(
                (saw.height_at([10.0, top_y]) - 10.0).abs() < 1e-9,
                "{direction}"
            );
        }
        // The hipped end is where `roof:direction` points: east here, a gable end in the west.
        let side = roof(RoofShape::SideHipped, 90.0);
        assert!((side.height_at([20.0, 4.0]) - 6.0).abs() < 1e-9);
        assert!((side.height_at([0.0, 4.0]) - 10.0).abs() < 1e-9);
        let side = roof(RoofShape::SideHipped, 270.0);
        assert!((side.height_at([0.0, 4.0]) - 6.0).abs() < 1e-9);
        assert!((side.height_at([20.0, 4.0]) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn gabled_has_one_ridge_along_the_long_side() {
        let (ring, axes) = rectangle();
        let roof = RoofSurface::new(
            RoofShape::Gabled,
            axes,
            Orientation::Along,
            &ring,
            None,
            None,
        )
        .with_heights(10.0, 4.0);
        let segments = roof.dividing_segments();
        assert_eq!(segments.len(), 1);
        let [p, q] = segments[0];
        // The ridge runs from (0, 4) to (20, 4) in some order.
        assert!((p[1] - 4.0).abs() < 1e-9 && (q[1] - 4.0).abs() < 1e-9);
        assert!(((p[0] - q[0]).abs() - 20.0).abs() < 1e-9);
        assert!((roof.height_at([5.0, 4.0]) - 10.0).abs() < 1e-12);
        assert!((roof.height_at([5.0, 0.0]) - 6.0).abs() < 1e-12);
        assert!((roof.height_at([5.0, 2.0]) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn across_turns_the_ridge() {
        let (ring, axes) = rectangle();
        let roof = RoofSurface::new(
            RoofShape::Gabled,
            axes,
            Orientation::Across,
            &ring,
            None,
            None,
        )
        .with_heights(10.0, 4.0);
        // Now the ridge is the line x = 10.
        assert!((roof.height_at([10.0, 1.0]) - 10.0).abs() < 1e-12);
        assert!((roof.height_at([0.0, 1.0]) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn skillion_descends_towards_its_direction() {
        let (ring, axes) = rectangle();
        // roof:direction = 90: the roof falls towards the east.
        let roof = RoofSurface::new(
            RoofShape::Skillion,
            axes,
            Orientation::Along,
            &ring,
            Some(90.0),
            None,
        )
        .with_heights(10.0, 2.0);
        assert!((roof.height_at([0.0, 3.0]) - 10.0).abs() < 1e-12);
        assert!((roof.height_at([20.0, 3.0]) - 8.0).abs() < 1e-12);
        assert!(roof.dividing_segments().is_empty());
    }
}

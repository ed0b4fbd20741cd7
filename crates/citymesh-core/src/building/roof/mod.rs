//! Roof shapes: the paper's eight and the rest of OpenStreetMap's Simple 3D Buildings table, each
//! as descending level functions (DLF) over the virtual rectangle and the convex virtual faces on
//! which the DLF is affine (docs/method.md section 6, paper Appendix A). Curved shapes (round,
//! dome, onion, cone) are sampled: their DLF is piecewise affine between sampled rings.
//!
//! Coordinates here are the alternative coordinates of the virtual rectangle, already turned for
//! `roof:orientation`: `a` runs along the ridge and `b` across it, both in [-1, 1]; `ra` and `rb`
//! are the rectangle's half-lengths along `a` and `b` in metres. The roof height of a point is
//! `h_top - h_roof * dlf(a, b)`.

mod crosspitched;
mod flat;
mod frustum;
mod gabled;
mod gambrel;
mod half_hipped;
mod hipped;
mod mansard;
mod pyramidal;
mod revolved;
mod round;
mod saltbox;
mod sawtooth;
mod side_half_hipped;
mod side_hipped;
mod skillion;

pub use crosspitched::Crosspitched;
pub use flat::Flat;
pub use frustum::{FRUSTUM_TOP, Frustum};
pub use gabled::Gabled;
pub use gambrel::{Gambrel, gambrel_profile};
pub use half_hipped::HalfHipped;
pub use hipped::Hipped;
pub use mansard::Mansard;
pub use pyramidal::Pyramidal;
pub use revolved::{Revolved, cone_profile, dome_profile, onion_profile};
pub use round::Round;
pub use saltbox::{SALTBOX_RIDGE, Saltbox};
pub use sawtooth::{SAWTOOTH_RISE, Sawtooth};
pub use side_half_hipped::SideHalfHipped;
pub use side_hipped::SideHipped;
pub use skillion::Skillion;

/// Where the profile of double and quadruple saltbox roofs bends (as GP and MP do for gambrel
/// and mansard): steep above, shallow below.
pub const SALTBOX_KINK: f64 = 0.3;

/// A point in alternative coordinates `[a, b]`.
pub type Alt = [f64; 2];

/// The roof shapes: the paper's eight first, then the rest of Simple 3D Buildings'.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RoofShape {
    Flat,
    Gabled,
    Hipped,
    Pyramidal,
    Skillion,
    HalfHipped,
    Gambrel,
    Mansard,
    Saltbox,
    DoubleSaltbox,
    QuadrupleSaltbox,
    SideHipped,
    SideHalfHipped,
    Sawtooth,
    Crosspitched,
    Round,
    Dome,
    Onion,
    Cone,
    Frustum,
}

impl RoofShape {
    /// How many shapes there are.
    pub const COUNT: usize = 20;

    pub const ALL: [RoofShape; Self::COUNT] = [
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
        RoofShape::Frustum,
    ];

    /// The shape an OSM `roof:shape` value names, if citymesh draws it. `many` and `complex`
    /// say the roof is drawn by its `roof:part`/`building:part` pieces: the outline itself is
    /// flat. `frustrum` is a common misspelling.
    pub fn from_tag(value: &str) -> Option<Self> {
        Some(match value.trim() {
            "flat" | "many" | "complex" => RoofShape::Flat,
            "gabled" => RoofShape::Gabled,
            "hipped" => RoofShape::Hipped,
            "pyramidal" => RoofShape::Pyramidal,
            "skillion" => RoofShape::Skillion,
            "half-hipped" | "half_hipped" => RoofShape::HalfHipped,
            "gambrel" => RoofShape::Gambrel,
            "mansard" => RoofShape::Mansard,
            "saltbox" => RoofShape::Saltbox,
            "double_saltbox" | "double-saltbox" => RoofShape::DoubleSaltbox,
            "quadruple_saltbox" | "quadruple-saltbox" => RoofShape::QuadrupleSaltbox,
            "side_hipped" | "side-hipped" => RoofShape::SideHipped,
            "side_half-hipped" | "side_half_hipped" | "side-half-hipped" => {
                RoofShape::SideHalfHipped
            }
            "sawtooth" => RoofShape::Sawtooth,
            "crosspitched" | "cross_pitched" | "cross-pitched" => RoofShape::Crosspitched,
            "round" => RoofShape::Round,
            "dome" => RoofShape::Dome,
            "onion" => RoofShape::Onion,
            "cone" => RoofShape::Cone,
            "frustum" | "frustrum" => RoofShape::Frustum,
            _ => return None,
        })
    }

    /// Whether the shape cuts a roof into many faces (sampled curves, rows of teeth), which a
    /// thin footprint may not take without slivers.
    pub fn has_many_faces(self) -> bool {
        matches!(
            self,
            RoofShape::Round
                | RoofShape::Dome
                | RoofShape::Onion
                | RoofShape::Cone
                | RoofShape::Sawtooth
        )
    }

    /// The OSM tag value.
    pub fn tag(self) -> &'static str {
        match self {
            RoofShape::Flat => "flat",
            RoofShape::Gabled => "gabled",
            RoofShape::Hipped => "hipped",
            RoofShape::Pyramidal => "pyramidal",
            RoofShape::Skillion => "skillion",
            RoofShape::HalfHipped => "half-hipped",
            RoofShape::Gambrel => "gambrel",
            RoofShape::Mansard => "mansard",
            RoofShape::Saltbox => "saltbox",
            RoofShape::DoubleSaltbox => "double_saltbox",
            RoofShape::QuadrupleSaltbox => "quadruple_saltbox",
            RoofShape::SideHipped => "side_hipped",
            RoofShape::SideHalfHipped => "side_half-hipped",
            RoofShape::Sawtooth => "sawtooth",
            RoofShape::Crosspitched => "crosspitched",
            RoofShape::Round => "round",
            RoofShape::Dome => "dome",
            RoofShape::Onion => "onion",
            RoofShape::Cone => "cone",
            RoofShape::Frustum => "frustum",
        }
    }
}

/// One roof family: its descending level function and its virtual faces.
pub trait RoofModel {
    /// The DLF at `(a, b)`: 0 at the top of the roof, 1 at the eaves.
    fn dlf(&self, p: Alt) -> f64;

    /// Convex, counter-clockwise polygons that tile the square [-1, 1]², on each of which the DLF is
    /// affine. Their edges inside the square are the shape's dividing segments.
    fn faces(&self) -> Vec<Vec<Alt>>;
}

/// The full square [-1, 1]², counter-clockwise.
pub(crate) fn square() -> Vec<Alt> {
    vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
}

/// Twice the signed area of a polygon (positive when counter-clockwise): the shoelace sum.
pub(crate) fn twice_signed_area(f: &[Alt]) -> f64 {
    (0..f.len())
        .map(|i| {
            let (p, q) = (f[i], f[(i + 1) % f.len()]);
            p[0] * q[1] - q[0] * p[1]
        })
        .sum()
}

/// The polygon counter-clockwise (reversed if it was not).
pub(crate) fn counter_clockwise(mut f: Vec<Alt>) -> Vec<Alt> {
    if twice_signed_area(&f) < 0.0 {
        f.reverse();
    }
    f
}

/// Drops repeated consecutive points (a face that degenerates at a limit parameter) and faces
/// without area.
pub(crate) fn tidy(faces: Vec<Vec<Alt>>) -> Vec<Vec<Alt>> {
    faces
        .into_iter()
        .filter_map(|mut f| {
            f.dedup_by(|p, q| (p[0] - q[0]).abs() < 1e-12 && (p[1] - q[1]).abs() < 1e-12);
            while f.len() > 1
                && (f[0][0] - f[f.len() - 1][0]).abs() < 1e-12
                && (f[0][1] - f[f.len() - 1][1]).abs() < 1e-12
            {
                f.pop();
            }
            (f.len() >= 3 && twice_signed_area(&f) > 1e-12).then_some(f)
        })
        .collect()
}

/// The model of a shape. `ra`, `rb`: half-lengths along and across the ridge (metres);
/// `parameter`: HE, GP or MP for half-hipped (and side-half-hipped), gambrel and mansard (and
/// their saltbox kin), or the ridge's place across a saltbox (defaults used when `None`).
pub fn model(
    shape: RoofShape,
    ra: f64,
    rb: f64,
    parameter: Option<f64>,
) -> Box<dyn RoofModel + Send + Sync> {
    use super::defaults::{GAMBREL_GP, HALF_HIPPED_HE, MANSARD_MP};
    match shape {
        RoofShape::Flat => Box::new(Flat),
        RoofShape::Gabled => Box::new(Gabled),
        RoofShape::Hipped => Box::new(Hipped::new(ra, rb)),
        RoofShape::Pyramidal => Box::new(Pyramidal),
        RoofShape::Skillion => Box::new(Skillion),
        RoofShape::HalfHipped => {
            Box::new(HalfHipped::new(ra, rb, parameter.unwrap_or(HALF_HIPPED_HE)))
        }
        RoofShape::Gambrel => Box::new(Gambrel::new(parameter.unwrap_or(GAMBREL_GP))),
        RoofShape::Mansard => Box::new(Mansard::new(ra, rb, parameter.unwrap_or(MANSARD_MP))),
        RoofShape::Saltbox => Box::new(Saltbox::new(parameter.unwrap_or(SALTBOX_RIDGE))),
        RoofShape::DoubleSaltbox => {
            Box::new(Gambrel::with_break(parameter.unwrap_or(SALTBOX_KINK)))
        }
        RoofShape::QuadrupleSaltbox => Box::new(Mansard::with_break(
            ra,
            rb,
            parameter.unwrap_or(SALTBOX_KINK),
        )),
        RoofShape::SideHipped => Box::new(SideHipped::new(ra, rb)),
        RoofShape::SideHalfHipped => Box::new(SideHalfHipped::new(
            ra,
            rb,
            parameter.unwrap_or(HALF_HIPPED_HE),
        )),
        RoofShape::Sawtooth => Box::new(Sawtooth::new(rb)),
        RoofShape::Crosspitched => Box::new(Crosspitched),
        RoofShape::Round => Box::new(Round::new()),
        RoofShape::Dome => Box::new(Revolved::new(dome_profile())),
        RoofShape::Onion => Box::new(Revolved::new(onion_profile())),
        RoofShape::Cone => Box::new(Revolved::new(cone_profile())),
        RoofShape::Frustum => Box::new(Frustum),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Checks what every model promises: faces tile the square, and the DLF is affine on each.
    pub fn check_model(m: &dyn RoofModel) {
        let faces = m.faces();
        let total: f64 = faces
            .iter()
            .map(|f| twice_signed_area(f) / 2.0)
            .inspect(|a| assert!(*a > 0.0, "a face is not counter-clockwise"))
            .sum();
        assert!(
            (total - 4.0).abs() < 1e-9,
            "faces cover {total}, not the square's 4"
        );
        for f in &faces {
            // Affine on the face: the DLF at the centroid of any three vertices equals the mean of
            // their DLFs, and likewise at the face's own centroid.
            let c = f.iter().fold([0.0, 0.0], |s, p| {
                [s[0] + p[0] / f.len() as f64, s[1] + p[1] / f.len() as f64]
            });
            for i in 0..f.len() {
                let (p, q) = (f[i], f[(i + 1) % f.len()]);
                let mid = [(p[0] + q[0] + c[0]) / 3.0, (p[1] + q[1] + c[1]) / 3.0];
                let expect = (m.dlf(p) + m.dlf(q) + m.dlf(c)) / 3.0;
                assert!(
                    (m.dlf(mid) - expect).abs() < 1e-9,
                    "DLF not affine on face {f:?}"
                );
            }
            for p in f {
                let d = m.dlf(*p);
                assert!(
                    (-1e-12..=1.0 + 1e-12).contains(&d),
                    "DLF {d} outside [0, 1] at {p:?}"
                );
            }
        }
    }
}

//! Roof shapes: the paper's eight, each as descending level functions (DLF) over the virtual
//! rectangle and the convex virtual faces on which the DLF is affine (docs/method.md section 6,
//! paper Appendix A).
//!
//! Coordinates here are the alternative coordinates of the virtual rectangle, already turned for
//! `roof:orientation`: `a` runs along the ridge and `b` across it, both in [-1, 1]; `ra` and `rb`
//! are the rectangle's half-lengths along `a` and `b` in metres. The roof height of a point is
//! `h_top - h_roof * dlf(a, b)`.

mod flat;
mod gabled;
mod gambrel;
mod half_hipped;
mod hipped;
mod mansard;
mod pyramidal;
mod skillion;

pub use flat::Flat;
pub use gabled::Gabled;
pub use gambrel::{Gambrel, gambrel_profile};
pub use half_hipped::HalfHipped;
pub use hipped::Hipped;
pub use mansard::Mansard;
pub use pyramidal::Pyramidal;
pub use skillion::Skillion;

/// A point in alternative coordinates `[a, b]`.
pub type Alt = [f64; 2];

/// The eight roof shapes of the paper.
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
}

impl RoofShape {
    pub const ALL: [RoofShape; 8] = [
        RoofShape::Flat,
        RoofShape::Gabled,
        RoofShape::Hipped,
        RoofShape::Pyramidal,
        RoofShape::Skillion,
        RoofShape::HalfHipped,
        RoofShape::Gambrel,
        RoofShape::Mansard,
    ];

    /// The shape an OSM `roof:shape` value names, if it is one of the eight.
    pub fn from_tag(value: &str) -> Option<Self> {
        Some(match value.trim() {
            "flat" => RoofShape::Flat,
            "gabled" => RoofShape::Gabled,
            "hipped" => RoofShape::Hipped,
            "pyramidal" => RoofShape::Pyramidal,
            "skillion" => RoofShape::Skillion,
            "half-hipped" | "half_hipped" => RoofShape::HalfHipped,
            "gambrel" => RoofShape::Gambrel,
            "mansard" => RoofShape::Mansard,
            _ => return None,
        })
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
            let area: f64 = (0..f.len())
                .map(|i| {
                    let (p, q) = (f[i], f[(i + 1) % f.len()]);
                    p[0] * q[1] - q[0] * p[1]
                })
                .sum();
            (f.len() >= 3 && area > 1e-12).then_some(f)
        })
        .collect()
}

/// The model of a shape. `ra`, `rb`: half-lengths along and across the ridge (metres);
/// `parameter`: HE, GP or MP for half-hipped, gambrel and mansard (defaults used when `None`).
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
            .map(|f| {
                (0..f.len())
                    .map(|i| {
                        let (p, q) = (f[i], f[(i + 1) % f.len()]);
                        (p[0] * q[1] - q[0] * p[1]) / 2.0
                    })
                    .sum::<f64>()
            })
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

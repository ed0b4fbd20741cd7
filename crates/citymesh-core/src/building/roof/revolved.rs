//! Roofs of revolution over the ellipse inscribed in the rectangle: dome, onion and cone. The
//! circle is a regular polygon of [`SECTORS`] sides (vertices on it, one at +a); the roof is a
//! profile of the polygonal radius rho (1 on the polygon), DLF = p(rho), linear between the
//! profile's points and 1 outside the polygon (the corners of the rectangle stay at the eaves).
//! On each sector between two of the profile's rings rho is affine, so the faces are triangles
//! at the centre, trapezoids between rings and, outside, the rest of each sector.

use super::{Alt, RoofModel, counter_clockwise, tidy};
use std::f64::consts::PI;

/// Sides of the polygon standing in for the circle.
pub const SECTORS: usize = 16;

/// Rings of the dome and round profiles between centre and eaves.
const RINGS: usize = 6;

/// A profile: (rho, DLF) from (0, 0) to (1, 1), rho increasing.
pub type Profile = Vec<(f64, f64)>;

/// A hemisphere: DLF = 1 - sqrt(1 - rho^2), sampled at rho = sin(k pi / 12).
pub fn dome_profile() -> Profile {
    (0..=RINGS)
        .map(|k| {
            let t = k as f64 * PI / (2 * RINGS) as f64;
            (t.sin(), 1.0 - t.cos())
        })
        .collect()
}

/// An onion drawn as a height field (its bulb cannot overhang the walls): steep at the eaves,
/// full in the middle, narrowing to a point.
pub fn onion_profile() -> Profile {
    vec![
        (0.0, 0.0),
        (0.08, 0.06),
        (0.2, 0.16),
        (0.4, 0.3),
        (0.6, 0.42),
        (0.8, 0.56),
        (0.93, 0.72),
        (1.0, 1.0),
    ]
}

/// A cone: DLF = rho.
pub fn cone_profile() -> Profile {
    vec![(0.0, 0.0), (1.0, 1.0)]
}

/// The profile's DLF at `t`: linear between its points, 1 from t = 1 on.
pub fn along_profile(profile: &[(f64, f64)], t: f64) -> f64 {
    if t >= 1.0 {
        return 1.0;
    }
    for w in profile.windows(2) {
        let ((t0, d0), (t1, d1)) = (w[0], w[1]);
        if t <= t1 {
            return d0 + (d1 - d0) * (t - t0) / (t1 - t0);
        }
    }
    1.0
}

pub struct Revolved {
    profile: Profile,
}

impl Revolved {
    pub fn new(profile: Profile) -> Self {
        Self { profile }
    }

    /// The polygonal radius of a point: the scale of the polygon through it.
    fn rho([a, b]: Alt) -> f64 {
        let step = 2.0 * PI / SECTORS as f64;
        let angle = b.atan2(a).rem_euclid(2.0 * PI);
        let j = ((angle / step).floor() as usize).min(SECTORS - 1);
        // The chord of sector j, by its unit normal at the sector's middle angle.
        let mid = (j as f64 + 0.5) * step;
        (a * mid.cos() + b * mid.sin()) / (step / 2.0).cos()
    }

    fn vertex(r: f64, j: usize) -> Alt {
        let angle = 2.0 * PI * (j % SECTORS) as f64 / SECTORS as f64;
        [r * angle.cos(), r * angle.sin()]
    }

    /// Where the ray from the centre through vertex j leaves the square.
    fn ray_end(j: usize) -> Alt {
        let [a, b] = Self::vertex(1.0, j);
        let m = a.abs().max(b.abs());
        [a / m, b / m]
    }
}

impl RoofModel for Revolved {
    fn dlf(&self, p: Alt) -> f64 {
        along_profile(&self.profile, Self::rho(p))
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let mut faces = Vec::new();
        for j in 0..SECTORS {
            for w in self.profile.windows(2) {
                let (r0, r1) = (w[0].0, w[1].0);
                let face = if r0 == 0.0 {
                    vec![[0.0, 0.0], Self::vertex(r1, j), Self::vertex(r1, j + 1)]
                } else {
                    vec![
                        Self::vertex(r0, j),
                        Self::vertex(r1, j),
                        Self::vertex(r1, j + 1),
                        Self::vertex(r0, j + 1),
                    ]
                };
                faces.push(counter_clockwise(face));
            }
            faces.push(counter_clockwise(vec![
                Self::vertex(1.0, j),
                Self::ray_end(j),
                Self::ray_end(j + 1),
                Self::vertex(1.0, j + 1),
            ]));
        }
        tidy(faces)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_profile_is_a_valid_model() {
        for profile in [dome_profile(), onion_profile(), cone_profile()] {
            super::super::tests::check_model(&Revolved::new(profile));
        }
    }

    #[test]
    fn the_polygon_s_vertices_lie_on_the_profile() {
        let dome = Revolved::new(dome_profile());
        assert_eq!(dome.dlf([0.0, 0.0]), 0.0);
        assert!((dome.dlf([0.5, 0.0]) - (1.0 - 0.75f64.sqrt())).abs() < 1e-12);
        assert_eq!(dome.dlf([1.0, 0.0]), 1.0);
        // The rectangle's corners stay at the eaves.
        assert_eq!(dome.dlf([1.0, 1.0]), 1.0);
        let cone = Revolved::new(cone_profile());
        let v = Revolved::vertex(0.3, 5);
        assert!((cone.dlf(v) - 0.3).abs() < 1e-12);
    }
}

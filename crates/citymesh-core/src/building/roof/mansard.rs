//! Mansard: a hipped roof whose four sides break at MP into a steep lower and a shallow upper part.
//! x_H as hipped; x_M = x_H + MP * rb / ra; DLF_y = g_MP(|b|);
//! DLF_x = 0 for |a| <= x_H, else g_MP((|a| - x_H) / (1 - x_H)), with g the gambrel profile.

use super::{Alt, RoofModel, gambrel_profile, tidy};

pub struct Mansard {
    x_h: f64,
    x_m: f64,
    mp: f64,
}

impl Mansard {
    /// MP is clamped to [0.5, 1].
    pub fn new(ra: f64, rb: f64, mp: f64) -> Self {
        Self::with_break(ra, rb, mp.clamp(0.5, 1.0))
    }

    /// A break anywhere in [0.05, 1]: below 0.5 the upper part is the steeper, as on a
    /// quadruple saltbox.
    pub fn with_break(ra: f64, rb: f64, mp: f64) -> Self {
        let mp = mp.clamp(0.05, 1.0);
        let x_h = (1.0 - rb / ra).clamp(0.0, 1.0 - 1e-9);
        Self {
            x_h,
            x_m: x_h + mp * (1.0 - x_h),
            mp,
        }
    }
}

impl RoofModel for Mansard {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        let dlf_x = if a.abs() <= self.x_h {
            0.0
        } else {
            gambrel_profile(self.mp, (a.abs() - self.x_h) / (1.0 - self.x_h))
        };
        dlf_x.max(gambrel_profile(self.mp, b.abs()))
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let (h, m, p) = (self.x_h, self.x_m, self.mp);
        tidy(vec![
            // Lower, steep faces between the eaves and the break rectangle |a| = x_M, |b| = MP.
            vec![[-1.0, -1.0], [1.0, -1.0], [m, -p], [-m, -p]],
            vec![[m, -p], [1.0, -1.0], [1.0, 1.0], [m, p]],
            vec![[-m, p], [m, p], [1.0, 1.0], [-1.0, 1.0]],
            vec![[-1.0, -1.0], [-m, -p], [-m, p], [-1.0, 1.0]],
            // Upper, shallow faces inside the break rectangle, meeting at the ridge.
            vec![[-m, -p], [m, -p], [h, 0.0], [-h, 0.0]],
            vec![[h, 0.0], [m, -p], [m, p]],
            vec![[-h, 0.0], [h, 0.0], [m, p], [-m, p]],
            vec![[-h, 0.0], [-m, p], [-m, -p]],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for mp in [0.5, 0.7, 0.95] {
            super::super::tests::check_model(&super::Mansard::new(10.0, 4.0, mp));
        }
        super::super::tests::check_model(&super::Mansard::new(4.0, 4.0, 0.7));
        super::super::tests::check_model(&super::Mansard::new(4.0, 10.0, 0.7));
        for mp in [0.05, 0.3] {
            super::super::tests::check_model(&super::Mansard::with_break(10.0, 4.0, mp));
        }
    }
}

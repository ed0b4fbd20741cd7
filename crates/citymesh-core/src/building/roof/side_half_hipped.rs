//! Side-half-hipped: a gable with one end (+a) half-hipped down to DLF = y_H = 1 - HE, as
//! half-hipped does at both ends: x_H = 1 - y_H rb / ra; DLF = max(|b|, DLF_x), DLF_x =
//! (a - x_H) ra / rb for a > x_H, else 0.

use super::{Alt, RoofModel, tidy};

pub struct SideHalfHipped {
    x_h: f64,
    y_h: f64,
    ra_over_rb: f64,
}

impl SideHalfHipped {
    /// HE is clamped to [0, 1]; the hip starts no further than the other end.
    pub fn new(ra: f64, rb: f64, he: f64) -> Self {
        let y_h = 1.0 - he.clamp(0.0, 1.0);
        let ra_over_rb = ra / rb;
        // With the hip reaching past the other end, HE is cut down to what the length allows.
        let x_h = (1.0 - y_h / ra_over_rb).clamp(-1.0 + 1e-9, 1.0);
        Self {
            x_h,
            y_h: ((1.0 - x_h) * ra_over_rb).min(y_h),
            ra_over_rb,
        }
    }
}

impl RoofModel for SideHalfHipped {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        let dlf_x = if a <= self.x_h {
            0.0
        } else {
            (a - self.x_h) * self.ra_over_rb
        };
        dlf_x.max(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let (x, y) = (self.x_h, self.y_h);
        tidy(vec![
            vec![[x, 0.0], [1.0, -y], [1.0, y]],
            vec![[-1.0, 0.0], [x, 0.0], [1.0, y], [1.0, 1.0], [-1.0, 1.0]],
            vec![[-1.0, -1.0], [1.0, -1.0], [1.0, -y], [x, 0.0], [-1.0, 0.0]],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for he in [0.0, 0.3, 0.7, 1.0] {
            for (ra, rb) in [(10.0, 4.0), (4.0, 10.0), (2.0, 7.25), (5.0, 5.0)] {
                super::super::tests::check_model(&super::SideHalfHipped::new(ra, rb, he));
            }
        }
    }
}

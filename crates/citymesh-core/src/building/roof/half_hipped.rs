//! Half-hipped: a gable whose ends are hipped down to DLF = y_H = 1 - HE.
//! x_H = 1 - y_H * rb / ra; DLF_x = 0 for |a| <= x_H, else (|a| - x_H) * ra / rb; DLF_y = |b|.
//!
//! When the ridge runs along the shorter side (`roof:orientation=across` on a long building),
//! x_H is negative: the two hips meet in the middle, along the segment a = 0, |b| <= -x_H ra / rb,
//! and the long sides become pentagons.

use super::{Alt, RoofModel, tidy};

pub struct HalfHipped {
    x_h: f64,
    y_h: f64,
    ra_over_rb: f64,
}

impl HalfHipped {
    /// HE is clamped to [0, 1].
    pub fn new(ra: f64, rb: f64, he: f64) -> Self {
        let y_h = 1.0 - he.clamp(0.0, 1.0);
        Self {
            x_h: (1.0 - y_h * rb / ra).min(1.0),
            y_h,
            ra_over_rb: ra / rb,
        }
    }
}

impl RoofModel for HalfHipped {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        let dlf_x = if a.abs() <= self.x_h {
            0.0
        } else {
            (a.abs() - self.x_h) * self.ra_over_rb
        };
        dlf_x.max(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let (x, y) = (self.x_h, self.y_h);
        if x < 0.0 {
            // Where the two hips meet at a = 0.
            let c = -x * self.ra_over_rb;
            return tidy(vec![
                vec![[0.0, -c], [1.0, -y], [1.0, y], [0.0, c]],
                vec![[0.0, c], [-1.0, y], [-1.0, -y], [0.0, -c]],
                vec![[0.0, c], [1.0, y], [1.0, 1.0], [-1.0, 1.0], [-1.0, y]],
                vec![[-1.0, -1.0], [1.0, -1.0], [1.0, -y], [0.0, -c], [-1.0, -y]],
            ]);
        }
        tidy(vec![
            vec![[x, 0.0], [1.0, -y], [1.0, y]],
            vec![[-x, 0.0], [-1.0, y], [-1.0, -y]],
            vec![
                [-x, 0.0],
                [x, 0.0],
                [1.0, y],
                [1.0, 1.0],
                [-1.0, 1.0],
                [-1.0, y],
            ],
            vec![
                [-1.0, -1.0],
                [1.0, -1.0],
                [1.0, -y],
                [x, 0.0],
                [-x, 0.0],
                [-1.0, -y],
            ],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for he in [0.0, 0.3, 0.7, 1.0] {
            // Along the long side, and across it (the hips meet in the middle).
            for (ra, rb) in [(10.0, 4.0), (4.0, 10.0), (2.0, 7.25), (5.0, 5.0)] {
                super::super::tests::check_model(&super::HalfHipped::new(ra, rb, he));
            }
        }
    }
}

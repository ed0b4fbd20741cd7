//! Side-hipped: a gable with one end (+a) hipped down to the eaves and the other a gable end.
//! The hip has the pitch of the sides: x_H = 1 - rb/ra as for hipped; DLF = max(|b|, DLF_x),
//! DLF_x = (a - x_H) / (1 - x_H) for a > x_H, else 0.

use super::{Alt, RoofModel, tidy};

pub struct SideHipped {
    x_h: f64,
}

impl SideHipped {
    pub fn new(ra: f64, rb: f64) -> Self {
        Self {
            x_h: (1.0 - rb / ra).clamp(0.0, 1.0 - 1e-9),
        }
    }
}

impl RoofModel for SideHipped {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        let x_h = self.x_h;
        let dlf_x = if a <= x_h {
            0.0
        } else {
            (a - x_h) / (1.0 - x_h)
        };
        dlf_x.max(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let x = self.x_h;
        tidy(vec![
            vec![[-1.0, -1.0], [1.0, -1.0], [x, 0.0], [-1.0, 0.0]],
            vec![[-1.0, 0.0], [x, 0.0], [1.0, 1.0], [-1.0, 1.0]],
            vec![[x, 0.0], [1.0, -1.0], [1.0, 1.0]],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for (ra, rb) in [(10.0, 4.0), (5.0, 5.0), (4.0, 10.0)] {
            super::super::tests::check_model(&super::SideHipped::new(ra, rb));
        }
    }
}

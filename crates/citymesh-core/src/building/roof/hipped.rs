//! Hipped: a ridge of half-length x_H = 1 - rb/ra and four planes of equal pitch.
//! DLF_x = 0 for |a| <= x_H, else (|a| - x_H) / (1 - x_H); DLF_y = |b|; DLF = max of both.

use super::{Alt, RoofModel, tidy};

pub struct Hipped {
    x_h: f64,
}

impl Hipped {
    pub fn new(ra: f64, rb: f64) -> Self {
        Self {
            x_h: (1.0 - rb / ra).clamp(0.0, 1.0 - 1e-9),
        }
    }
}

impl RoofModel for Hipped {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        let x_h = self.x_h;
        let dlf_x = if a.abs() <= x_h {
            0.0
        } else {
            (a.abs() - x_h) / (1.0 - x_h)
        };
        dlf_x.max(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let x = self.x_h;
        tidy(vec![
            vec![[-1.0, -1.0], [1.0, -1.0], [x, 0.0], [-x, 0.0]],
            vec![[-x, 0.0], [x, 0.0], [1.0, 1.0], [-1.0, 1.0]],
            vec![[x, 0.0], [1.0, -1.0], [1.0, 1.0]],
            vec![[-x, 0.0], [-1.0, 1.0], [-1.0, -1.0]],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Hipped::new(10.0, 4.0));
        super::super::tests::check_model(&super::Hipped::new(5.0, 5.0));
        super::super::tests::check_model(&super::Hipped::new(4.0, 10.0));
    }
}

//! Saltbox: a gable whose ridge stands off the middle, so one slope is longer than the other.
//! The ridge runs along `a` at b = b_R (default [`SALTBOX_RIDGE`]: a quarter of the width from the
//! +b side); DLF = (b - b_R) / (1 - b_R) on the short side, (b_R - b) / (1 + b_R) on the long one.

use super::{Alt, RoofModel};

/// Where the ridge stands across the rectangle (b in [-1, 1]).
pub const SALTBOX_RIDGE: f64 = 0.5;

pub struct Saltbox {
    ridge: f64,
}

impl Saltbox {
    /// `ridge` is clamped inside (-1, 1).
    pub fn new(ridge: f64) -> Self {
        Self {
            ridge: ridge.clamp(-0.95, 0.95),
        }
    }
}

impl RoofModel for Saltbox {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        let r = self.ridge;
        if b >= r {
            (b - r) / (1.0 - r)
        } else {
            (r - b) / (1.0 + r)
        }
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let r = self.ridge;
        vec![
            vec![[-1.0, -1.0], [1.0, -1.0], [1.0, r], [-1.0, r]],
            vec![[-1.0, r], [1.0, r], [1.0, 1.0], [-1.0, 1.0]],
        ]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for r in [0.0, 0.5, -0.3] {
            super::super::tests::check_model(&super::Saltbox::new(r));
        }
    }
}

//! Gambrel: a gable whose two sides break at |b| = GP into a shallow upper and a steep lower part.
//! g(t) = (1 - GP) / GP * t for t <= GP, else 1 - GP / (1 - GP) * (1 - t); DLF_y = g(|b|).

use super::{Alt, RoofModel};

pub struct Gambrel {
    gp: f64,
}

impl Gambrel {
    /// GP is clamped to [0.5, 1].
    pub fn new(gp: f64) -> Self {
        Self {
            gp: gp.clamp(0.5, 1.0),
        }
    }

    /// A break anywhere in [0.05, 1]: below 0.5 the upper part is the steeper, as on a double
    /// saltbox.
    pub fn with_break(p: f64) -> Self {
        Self {
            gp: p.clamp(0.05, 1.0),
        }
    }
}

/// The gambrel profile g(t) for break point `p` in (0, 1].
pub fn gambrel_profile(p: f64, t: f64) -> f64 {
    if t <= p {
        (1.0 - p) / p * t
    } else {
        1.0 - p / (1.0 - p) * (1.0 - t)
    }
}

impl RoofModel for Gambrel {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        gambrel_profile(self.gp, b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let g = self.gp;
        super::tidy(vec![
            vec![[-1.0, -1.0], [1.0, -1.0], [1.0, -g], [-1.0, -g]],
            vec![[-1.0, -g], [1.0, -g], [1.0, 0.0], [-1.0, 0.0]],
            vec![[-1.0, 0.0], [1.0, 0.0], [1.0, g], [-1.0, g]],
            vec![[-1.0, g], [1.0, g], [1.0, 1.0], [-1.0, 1.0]],
        ])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for gp in [0.5, 0.7, 0.9] {
            super::super::tests::check_model(&super::Gambrel::new(gp));
        }
        for p in [0.05, 0.3] {
            super::super::tests::check_model(&super::Gambrel::with_break(p));
        }
    }
}

//! Round: a barrel vault whose axis runs along `a`, a half circle across it: DLF = 1 - sqrt(1 -
//! b^2), linear between b = ±sin(k pi / 12), k = 0..6, so each strip between two of those is
//! one plane.

use super::{Alt, RoofModel};
use std::f64::consts::PI;

/// Strips on each side of the axis.
const STRIPS: usize = 6;

pub struct Round;

/// The strips' edges from the axis outwards: (|b|, DLF).
fn samples() -> Vec<(f64, f64)> {
    (0..=STRIPS)
        .map(|k| {
            let t = k as f64 * PI / (2 * STRIPS) as f64;
            (t.sin(), 1.0 - t.cos())
        })
        .collect()
}

impl RoofModel for Round {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        let t = b.abs().min(1.0);
        let s = samples();
        for w in s.windows(2) {
            let ((b0, d0), (b1, d1)) = (w[0], w[1]);
            if t <= b1 {
                return d0 + (d1 - d0) * (t - b0) / (b1 - b0);
            }
        }
        1.0
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let s = samples();
        let mut faces = Vec::with_capacity(2 * STRIPS);
        for w in s.windows(2) {
            let (b0, b1) = (w[0].0, w[1].0);
            faces.push(vec![[-1.0, b0], [1.0, b0], [1.0, b1], [-1.0, b1]]);
            faces.push(vec![[-1.0, -b1], [1.0, -b1], [1.0, -b0], [-1.0, -b0]]);
        }
        faces
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_a_valid_model_on_the_half_circle() {
        super::super::tests::check_model(&Round);
        assert_eq!(Round.dlf([0.3, 0.0]), 0.0);
        assert!((Round.dlf([0.0, 0.5]) - (1.0 - 0.75f64.sqrt())).abs() < 1e-12);
        assert!((Round.dlf([0.0, -1.0]) - 1.0).abs() < 1e-12);
    }
}

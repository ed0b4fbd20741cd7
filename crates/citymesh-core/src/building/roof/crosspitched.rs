//! Crosspitched: two gables crossing at the middle, one with its ridge along `a`, one along `b`;
//! the roof is the higher of the two: DLF = min(|a|, |b|). Valleys run along the diagonals.

use super::{Alt, RoofModel, counter_clockwise};

pub struct Crosspitched;

impl RoofModel for Crosspitched {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        a.abs().min(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let mut faces = Vec::with_capacity(8);
        for (sa, sb) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
            // Either side of the quadrant's diagonal: |b| < |a| (the gable along `a`) and
            // |a| < |b| (the gable along `b`).
            faces.push(counter_clockwise(vec![[0.0, 0.0], [sa, 0.0], [sa, sb]]));
            faces.push(counter_clockwise(vec![[0.0, 0.0], [sa, sb], [0.0, sb]]));
        }
        faces
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Crosspitched);
    }
}

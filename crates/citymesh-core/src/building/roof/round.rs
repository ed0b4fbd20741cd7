//! Round: a barrel vault whose axis runs along `a`, a half circle across it: DLF = 1 - sqrt(1 -
//! b^2), the dome's profile ([`dome_profile`]) over |b|: linear between b = ±sin(k pi / 12),
//! k = 0..6, so each strip between two of those is one plane.

use super::revolved::{Profile, along_profile, dome_profile};
use super::{Alt, RoofModel};

pub struct Round {
    /// The strips' edges from the axis outwards: (|b|, DLF).
    profile: Profile,
}

impl Round {
    pub fn new() -> Self {
        Self {
            profile: dome_profile(),
        }
    }
}

impl Default for Round {
    fn default() -> Self {
        Self::new()
    }
}

impl RoofModel for Round {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        along_profile(&self.profile, b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let mut faces = Vec::with_capacity(2 * self.profile.len());
        for w in self.profile.windows(2) {
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
        let round = Round::new();
        super::super::tests::check_model(&round);
        assert_eq!(round.dlf([0.3, 0.0]), 0.0);
        assert!((round.dlf([0.0, 0.5]) - (1.0 - 0.75f64.sqrt())).abs() < 1e-12);
        assert!((round.dlf([0.0, -1.0]) - 1.0).abs() < 1e-12);
    }
}

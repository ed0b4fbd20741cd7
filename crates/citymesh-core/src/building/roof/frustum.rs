//! Frustum: a pyramid cut flat at half its height's run: a flat top over the middle
//! [-t, t]^2 (t = [`FRUSTUM_TOP`]) and four sloped sides down to the eaves:
//! DLF = max(0, (max(|a|, |b|) - t) / (1 - t)).

use super::{Alt, RoofModel};

/// The flat top's half-size in alternative coordinates.
pub const FRUSTUM_TOP: f64 = 0.5;

pub struct Frustum;

impl RoofModel for Frustum {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        ((a.abs().max(b.abs()) - FRUSTUM_TOP) / (1.0 - FRUSTUM_TOP)).max(0.0)
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let t = FRUSTUM_TOP;
        vec![
            vec![[-t, -t], [t, -t], [t, t], [-t, t]],
            vec![[-1.0, -1.0], [1.0, -1.0], [t, -t], [-t, -t]],
            vec![[1.0, -1.0], [1.0, 1.0], [t, t], [t, -t]],
            vec![[1.0, 1.0], [-1.0, 1.0], [-t, t], [t, t]],
            vec![[-1.0, 1.0], [-1.0, -1.0], [-t, -t], [-t, t]],
        ]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Frustum);
    }
}

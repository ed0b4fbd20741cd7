//! Gabled: two planes meeting at a ridge along the long axis. DLF_y = |b|.

use super::{Alt, RoofModel};

pub struct Gabled;

impl RoofModel for Gabled {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        b.abs()
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        vec![
            vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 0.0], [-1.0, 0.0]],
            vec![[-1.0, 0.0], [1.0, 0.0], [1.0, 1.0], [-1.0, 1.0]],
        ]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Gabled);
    }
}

//! Skillion: one plane. In its own frame, whose `a` axis points along `roof:direction`, the roof
//! descends towards that direction: DLF = (a + 1) / 2.

use super::{Alt, RoofModel, square};

pub struct Skillion;

impl RoofModel for Skillion {
    fn dlf(&self, [a, _]: Alt) -> f64 {
        (a + 1.0) / 2.0
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        vec![square()]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Skillion);
    }
}

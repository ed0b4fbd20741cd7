//! Flat: the roof is the footprint at the top height.

use super::{Alt, RoofModel, square};

pub struct Flat;

impl RoofModel for Flat {
    fn dlf(&self, _: Alt) -> f64 {
        0.0
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        vec![square()]
    }
}

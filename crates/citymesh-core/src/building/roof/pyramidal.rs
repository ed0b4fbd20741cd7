//! Pyramidal: four triangles meeting at the centre. DLF = max(|a|, |b|).

use super::{Alt, RoofModel};

pub struct Pyramidal;

impl RoofModel for Pyramidal {
    fn dlf(&self, [a, b]: Alt) -> f64 {
        a.abs().max(b.abs())
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let o = [0.0, 0.0];
        vec![
            vec![o, [1.0, -1.0], [1.0, 1.0]],
            vec![o, [1.0, 1.0], [-1.0, 1.0]],
            vec![o, [-1.0, 1.0], [-1.0, -1.0]],
            vec![o, [-1.0, -1.0], [1.0, -1.0]],
        ]
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        super::super::tests::check_model(&super::Pyramidal);
    }
}

//! Sawtooth: a row of `n` sheds across the rectangle, each rising along +b over 9/10 of its width
//! and falling steeply over the last tenth (the glazed side). Within tooth i, whose width in b
//! is w = 2/n and which starts at b_i = -1 + i w, with t = (b - b_i) / w:
//! DLF = 1 - t / T for t <= T = 0.9, else (t - T) / (1 - T).

use super::{Alt, RoofModel};

/// The share of a tooth's width its long slope takes.
pub const SAWTOOTH_RISE: f64 = 0.9;
/// Wanted width of one tooth, metres (the count is rounded, 2 to 16).
pub const SAWTOOTH_WIDTH_M: f64 = 8.0;

pub struct Sawtooth {
    n: usize,
}

impl Sawtooth {
    /// Teeth about [`SAWTOOTH_WIDTH_M`] wide across a rectangle `2 rb` wide.
    pub fn new(rb: f64) -> Self {
        Self { n: Self::teeth(rb) }
    }

    /// How many teeth a rectangle `2 rb` wide gets.
    pub fn teeth(rb: f64) -> usize {
        ((2.0 * rb / SAWTOOTH_WIDTH_M).round() as usize).clamp(2, 16)
    }

    fn width(&self) -> f64 {
        2.0 / self.n as f64
    }
}

impl RoofModel for Sawtooth {
    fn dlf(&self, [_, b]: Alt) -> f64 {
        let w = self.width();
        let i = (((b + 1.0) / w).floor() as usize).min(self.n - 1);
        let t = ((b + 1.0 - i as f64 * w) / w).clamp(0.0, 1.0);
        if t <= SAWTOOTH_RISE {
            1.0 - t / SAWTOOTH_RISE
        } else {
            (t - SAWTOOTH_RISE) / (1.0 - SAWTOOTH_RISE)
        }
    }
    fn faces(&self) -> Vec<Vec<Alt>> {
        let w = self.width();
        let mut faces = Vec::with_capacity(2 * self.n);
        for i in 0..self.n {
            let b0 = -1.0 + i as f64 * w;
            let top = b0 + SAWTOOTH_RISE * w;
            let b1 = if i + 1 == self.n { 1.0 } else { b0 + w };
            faces.push(vec![[-1.0, b0], [1.0, b0], [1.0, top], [-1.0, top]]);
            faces.push(vec![[-1.0, top], [1.0, top], [1.0, b1], [-1.0, b1]]);
        }
        faces
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn is_a_valid_model() {
        for rb in [4.0, 8.0, 20.0, 100.0] {
            super::super::tests::check_model(&super::Sawtooth::new(rb));
        }
        assert_eq!(super::Sawtooth::teeth(4.0), 2);
        assert_eq!(super::Sawtooth::teeth(20.0), 5);
        assert_eq!(super::Sawtooth::teeth(1000.0), 16);
    }
}

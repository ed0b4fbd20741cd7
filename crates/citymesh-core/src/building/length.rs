//! The length of a planar vector, the one measure every footprint computation takes.

/// `sqrt(dx² + dy²)`. Building coordinates are metres within a few kilometres of the frame's
/// origin, far from where the squares could overflow, so the plain formula is exact enough and
/// several times cheaper than `f64::hypot`.
#[inline]
pub fn planar_length(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

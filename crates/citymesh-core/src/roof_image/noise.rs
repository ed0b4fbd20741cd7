//! Deterministic value noise for textures: a hash of integer lattice points, smoothly
//! interpolated, summed over octaves.

/// A pseudo-random value in [0, 1) for a lattice point and a seed.
#[inline]
pub fn hash01(x: i64, y: i64, seed: u64) -> f32 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ seed.wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in [0, 1) at `(x, y)` lattice units.
pub fn value(x: f64, y: f64, seed: u64) -> f32 {
    let (xf, yf) = (x.floor(), y.floor());
    let (xi, yi) = (xf as i64, yf as i64);
    let s = |t: f64| (t * t * (3.0 - 2.0 * t)) as f32;
    let (tx, ty) = (s(x - xf), s(y - yf));
    let a = hash01(xi, yi, seed);
    let b = hash01(xi + 1, yi, seed);
    let c = hash01(xi, yi + 1, seed);
    let d = hash01(xi + 1, yi + 1, seed);
    let top = a + (b - a) * tx;
    let bottom = c + (d - c) * tx;
    top + (bottom - top) * ty
}

/// Fractal value noise in [0, 1): `octaves` layers, each twice as fine and half as strong.
pub fn fractal(x: f64, y: f64, octaves: u32, seed: u64) -> f32 {
    let (mut sum, mut weight, mut total, mut f) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        sum += weight * value(x * f, y * f, seed.wrapping_add(u64::from(o)));
        total += weight;
        weight *= 0.5;
        f *= 2.0;
    }
    sum / total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_stays_in_range_and_repeats() {
        for i in 0..500 {
            let (x, y) = (i as f64 * 0.37 - 50.0, i as f64 * 0.71 - 80.0);
            let v = fractal(x, y, 4, 7);
            assert!((0.0..1.0).contains(&v), "{v}");
            assert_eq!(v, fractal(x, y, 4, 7));
        }
        // Value noise equals the lattice hash at lattice points.
        assert_eq!(value(3.0, -2.0, 5), hash01(3, -2, 5));
    }
}

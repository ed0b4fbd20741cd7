//! Earth-centred, Earth-fixed (ECEF) coordinates on the WGS84 ellipsoid, for 3D Tiles content.
//!
//! Heights are taken as heights above the ellipsoid. citymesh's heights are SRTM's, above the
//! EGM96 geoid; citymesh does not apply the geoid undulation (about +48 m at Karlsruhe), so its
//! 3D Tiles sit that much low against an ellipsoid globe, and line up with SRTM-based terrain.

use super::{WGS84_A, WGS84_E2};

/// ECEF `[x, y, z]` metres of a point at `lon`, `lat` (degrees) and `height` (metres).
pub fn geodetic_to_ecef(lon: f64, lat: f64, height: f64) -> [f64; 3] {
    let (sl, cl) = lon.to_radians().sin_cos();
    let (sp, cp) = lat.to_radians().sin_cos();
    let n = WGS84_A / (1.0 - WGS84_E2 * sp * sp).sqrt();
    [
        (n + height) * cp * cl,
        (n + height) * cp * sl,
        (n * (1.0 - WGS84_E2) + height) * sp,
    ]
}

/// `(lon, lat, height)` of an ECEF point (Bowring's method, iterated to sub-millimetre).
pub fn ecef_to_geodetic([x, y, z]: [f64; 3]) -> (f64, f64, f64) {
    let lon = y.atan2(x);
    let p = x.hypot(y);
    let mut lat = z.atan2(p * (1.0 - WGS84_E2));
    let mut h = 0.0;
    for _ in 0..6 {
        let s = lat.sin();
        let n = WGS84_A / (1.0 - WGS84_E2 * s * s).sqrt();
        h = p / lat.cos() - n;
        lat = z.atan2(p * (1.0 - WGS84_E2 * n / (n + h)));
    }
    (lon.to_degrees(), lat.to_degrees(), h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_known_points() {
        let e = geodetic_to_ecef(0.0, 0.0, 0.0);
        assert!((e[0] - WGS84_A).abs() < 1e-6 && e[1].abs() < 1e-6 && e[2].abs() < 1e-6);
        let p = geodetic_to_ecef(8.4044, 49.0135, 118.0);
        let (lon, lat, h) = ecef_to_geodetic(p);
        assert!((lon - 8.4044).abs() < 1e-11 && (lat - 49.0135).abs() < 1e-11);
        assert!((h - 118.0).abs() < 1e-6);
    }
}

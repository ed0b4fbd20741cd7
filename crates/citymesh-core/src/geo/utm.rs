//! Universal Transverse Mercator on WGS84: geographic coordinates to a zone's easting and
//! northing (Krüger's series to the third order of the third flattening, millimetre accurate
//! within a zone), for imagery delivered in UTM.

use super::local_frame::WGS84_A;

/// WGS84 flattening.
const F: f64 = 1.0 / 298.257_223_563;
/// UTM scale on the central meridian.
const K0: f64 = 0.9996;

/// A UTM zone: 1 to 60, and the hemisphere (false northing 10,000 km in the south).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UtmZone {
    pub zone: u8,
    pub south: bool,
}

impl UtmZone {
    pub fn new(zone: u8, south: bool) -> Option<Self> {
        (1..=60).contains(&zone).then_some(Self { zone, south })
    }

    /// The zone's central meridian, degrees.
    pub fn central_meridian(&self) -> f64 {
        f64::from(self.zone) * 6.0 - 183.0
    }

    /// Easting and northing (metres) of a longitude and latitude (degrees).
    pub fn project(&self, lon: f64, lat: f64) -> [f64; 2] {
        let n = F / (2.0 - F);
        let big_a = WGS84_A / (1.0 + n) * (1.0 + n * n / 4.0 + n.powi(4) / 64.0);
        let alpha = [
            n / 2.0 - 2.0 * n * n / 3.0 + 5.0 * n.powi(3) / 16.0,
            13.0 * n * n / 48.0 - 3.0 * n.powi(3) / 5.0,
            61.0 * n.powi(3) / 240.0,
        ];
        let phi = lat.to_radians();
        let dl = (lon - self.central_meridian()).to_radians();
        let c = 2.0 * n.sqrt() / (1.0 + n);
        let t = (phi.sin().atanh() - c * (c * phi.sin()).atanh()).sinh();
        let xi = t.atan2(dl.cos());
        let eta = (dl.sin() / (1.0 + t * t).sqrt()).atanh();
        let (mut e, mut nn) = (eta, xi);
        for (j, a) in alpha.iter().enumerate() {
            let k = 2.0 * (j as f64 + 1.0);
            e += a * (k * xi).cos() * (k * eta).sinh();
            nn += a * (k * xi).sin() * (k * eta).cosh();
        }
        [
            500_000.0 + K0 * big_a * e,
            if self.south { 10_000_000.0 } else { 0.0 } + K0 * big_a * nn,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_central_meridian_maps_to_the_meridian_arc() {
        let z = UtmZone::new(32, false).unwrap();
        assert_eq!(z.central_meridian(), 9.0);
        let [e, n] = z.project(9.0, 0.0);
        assert!((e - 500_000.0).abs() < 1e-6 && n.abs() < 1e-6);
        // The WGS84 meridian arc to 45 degrees is 4,984,944.378 m; UTM scales it by 0.9996.
        let [e, n] = z.project(9.0, 45.0);
        assert!((e - 500_000.0).abs() < 1e-6);
        assert!((n - 4_984_944.378 * K0).abs() < 0.01, "{n}");
        // East and west of the central meridian mirror each other; the south has a false northing.
        let [e1, n1] = z.project(10.0, 49.0);
        let [e2, n2] = z.project(8.0, 49.0);
        assert!((e1 - 500_000.0 + e2 - 500_000.0).abs() < 1e-6 && (n1 - n2).abs() < 1e-6);
        let south = UtmZone::new(32, true).unwrap();
        let [_, ns] = south.project(9.0, -45.0);
        assert!((ns - (10_000_000.0 - 4_984_944.378 * K0)).abs() < 0.01);
        // One degree of longitude at 49 N is about 73.1 km (times 0.9996 and a little growth
        // away from the meridian).
        assert!((e1 - e2 - 2.0 * 73_175.0).abs() < 200.0, "{}", e1 - e2);
        assert!(UtmZone::new(0, false).is_none() && UtmZone::new(61, false).is_none());
    }
}

//! Web Mercator XYZ ("slippy map") tile coordinates.

use super::{GeoBbox, MAX_MERCATOR_LAT};
use std::f64::consts::PI;

/// The deepest zoom level any XYZ tile can have here (2^30 tiles a side).
pub const MAX_ZOOM: u8 = 30;

/// Why a tile coordinate was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TileError {
    #[error("zoom {0} is outside 0..={MAX_ZOOM}")]
    ZoomOutOfRange(u32),
    #[error("x {x} is outside 0..{limit} for zoom {z}")]
    XOutOfRange { z: u8, x: u32, limit: u64 },
    #[error("y {y} is outside 0..{limit} for zoom {z}")]
    YOutOfRange { z: u8, y: u32, limit: u64 },
}

/// A checked XYZ tile: `x` counts from 180 W eastwards, `y` from the north (85.0511 N) southwards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileCoord {
    pub z: u8,
    pub x: u32,
    pub y: u32,
}

impl TileCoord {
    /// Checks `x` and `y` against the size of zoom `z`.
    ///
    /// ```
    /// use citymesh_core::geo::TileCoord;
    /// assert!(TileCoord::new(16, 34_297, 22_502).is_ok());
    /// assert!(TileCoord::new(2, 4, 0).is_err());
    /// ```
    pub fn new(z: u32, x: u32, y: u32) -> Result<Self, TileError> {
        if z > u32::from(MAX_ZOOM) {
            return Err(TileError::ZoomOutOfRange(z));
        }
        let z = z as u8;
        let limit = 1u64 << z;
        if u64::from(x) >= limit {
            return Err(TileError::XOutOfRange { z, x, limit });
        }
        if u64::from(y) >= limit {
            return Err(TileError::YOutOfRange { z, y, limit });
        }
        Ok(Self { z, x, y })
    }

    /// The tile that contains a point.
    pub fn containing(z: u8, lon: f64, lat: f64) -> Self {
        let n = (1u64 << z) as f64;
        let lat = lat.clamp(-MAX_MERCATOR_LAT, MAX_MERCATOR_LAT);
        let x = ((lon + 180.0) / 360.0 * n).floor().clamp(0.0, n - 1.0);
        let y = (mercator_y(lat) * n).floor().clamp(0.0, n - 1.0);
        Self {
            z,
            x: x as u32,
            y: y as u32,
        }
    }

    /// The tile's extent in degrees.
    pub fn bounds(&self) -> GeoBbox {
        let n = (1u64 << self.z) as f64;
        let lon = |x: f64| x / n * 360.0 - 180.0;
        let lat = |y: f64| (PI * (1.0 - 2.0 * y / n)).sinh().atan().to_degrees();
        let (x, y) = (f64::from(self.x), f64::from(self.y));
        // A checked tile has west < east and south < north; clamp guards the last ulp at the poles.
        let clamp = |l: f64| l.clamp(-MAX_MERCATOR_LAT, MAX_MERCATOR_LAT);
        GeoBbox::from_ordered(lon(x), clamp(lat(y + 1.0)), lon(x + 1.0), clamp(lat(y)))
    }
}

/// The Web Mercator y of a latitude in 0 (north edge) ..= 1 (south edge).
pub fn mercator_y(lat: f64) -> f64 {
    let phi = lat.to_radians();
    (1.0 - (phi.tan() + 1.0 / phi.cos()).ln() / PI) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn karlsruhe_palace_tile() {
        // The palace (49.0135 N, 8.4044 E) lies in z16 tile 34297/22502 (the OSM wiki formula, worked out by hand).
        let t = TileCoord::containing(16, 8.4044, 49.0135);
        assert_eq!((t.x, t.y), (34_297, 22_502));
        let b = t.bounds();
        assert!(b.contains(8.4044, 49.0135));
        assert!((b.max_lon() - b.min_lon() - 360.0 / 65_536.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_out_of_range() {
        assert_eq!(TileCoord::new(31, 0, 0), Err(TileError::ZoomOutOfRange(31)));
        assert_eq!(
            TileCoord::new(1, 2, 0),
            Err(TileError::XOutOfRange {
                z: 1,
                x: 2,
                limit: 2
            })
        );
        assert_eq!(
            TileCoord::new(1, 0, 2),
            Err(TileError::YOutOfRange {
                z: 1,
                y: 2,
                limit: 2
            })
        );
        let world = TileCoord::new(0, 0, 0).unwrap().bounds();
        assert_eq!(world.min_lon(), -180.0);
        assert!((world.max_lat() - MAX_MERCATOR_LAT).abs() < 1e-9);
    }
}

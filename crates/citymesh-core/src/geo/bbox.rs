//! A validated geographic bounding box in WGS84 degrees.

use std::fmt;
use std::str::FromStr;

/// The latitude limit of Web Mercator: the tile grid, and so citymesh, ends here.
pub const MAX_MERCATOR_LAT: f64 = 85.051_128_779_806_59;

/// Why a bounding box was refused. Each message says what to fix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BboxError {
    #[error("expected four comma-separated numbers minLon,minLat,maxLon,maxLat, got {0} values")]
    WrongCount(usize),
    #[error("value {index} ('{text}') is not a number")]
    NotANumber { index: usize, text: String },
    #[error("value {index} is {value}, which is not a finite number")]
    NotFinite { index: usize, value: f64 },
    #[error("longitude {0} is outside -180..180")]
    LongitudeOutOfRange(f64),
    #[error("latitude {0} is outside -85.0511..85.0511 (the Web Mercator limit)")]
    LatitudeOutOfRange(f64),
    #[error(
        "minLon {min} must be smaller than maxLon {max} (the order is minLon,minLat,maxLon,maxLat)"
    )]
    InvertedLongitude { min: f64, max: f64 },
    #[error(
        "minLat {min} must be smaller than maxLat {max} (the order is minLon,minLat,maxLon,maxLat)"
    )]
    InvertedLatitude { min: f64, max: f64 },
}

/// A bounding box `[min_lon, max_lon] x [min_lat, max_lat]` in degrees, with `min < max` on both
/// axes, finite values and latitudes inside the Web Mercator range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoBbox {
    min_lon: f64,
    min_lat: f64,
    max_lon: f64,
    max_lat: f64,
}

impl GeoBbox {
    /// Checks and builds a bounding box.
    ///
    /// ```
    /// use citymesh_core::geo::GeoBbox;
    /// let b = GeoBbox::new(8.39, 49.04, 8.41, 49.06).unwrap();
    /// assert_eq!(b.center(), (8.4, 49.05));
    /// assert!(GeoBbox::new(8.41, 49.04, 8.39, 49.06).is_err());
    /// ```
    pub fn new(min_lon: f64, min_lat: f64, max_lon: f64, max_lat: f64) -> Result<Self, BboxError> {
        for (index, value) in [min_lon, min_lat, max_lon, max_lat].into_iter().enumerate() {
            if !value.is_finite() {
                return Err(BboxError::NotFinite { index, value });
            }
        }
        for lon in [min_lon, max_lon] {
            if !(-180.0..=180.0).contains(&lon) {
                return Err(BboxError::LongitudeOutOfRange(lon));
            }
        }
        for lat in [min_lat, max_lat] {
            if !(-MAX_MERCATOR_LAT..=MAX_MERCATOR_LAT).contains(&lat) {
                return Err(BboxError::LatitudeOutOfRange(lat));
            }
        }
        if min_lon >= max_lon {
            return Err(BboxError::InvertedLongitude {
                min: min_lon,
                max: max_lon,
            });
        }
        if min_lat >= max_lat {
            return Err(BboxError::InvertedLatitude {
                min: min_lat,
                max: max_lat,
            });
        }
        Ok(Self {
            min_lon,
            min_lat,
            max_lon,
            max_lat,
        })
    }

    /// A box from values the caller knows to be valid and ordered (tile math).
    pub(crate) fn from_ordered(min_lon: f64, min_lat: f64, max_lon: f64, max_lat: f64) -> Self {
        Self {
            min_lon,
            min_lat,
            max_lon,
            max_lat,
        }
    }

    pub fn min_lon(&self) -> f64 {
        self.min_lon
    }
    pub fn min_lat(&self) -> f64 {
        self.min_lat
    }
    pub fn max_lon(&self) -> f64 {
        self.max_lon
    }
    pub fn max_lat(&self) -> f64 {
        self.max_lat
    }

    /// The centre `(lon, lat)`.
    pub fn center(&self) -> (f64, f64) {
        (
            (self.min_lon + self.max_lon) / 2.0,
            (self.min_lat + self.max_lat) / 2.0,
        )
    }

    /// The area in square kilometres on the WGS84 ellipsoid, from the local frame at the centre.
    pub fn area_km2(&self) -> f64 {
        let (lon, lat) = self.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let (w, h) = frame.metres_per_degree();
        (self.max_lon - self.min_lon) * w * (self.max_lat - self.min_lat) * h / 1e6
    }

    /// Whether the point lies inside or on the border.
    pub fn contains(&self, lon: f64, lat: f64) -> bool {
        (self.min_lon..=self.max_lon).contains(&lon) && (self.min_lat..=self.max_lat).contains(&lat)
    }

    /// Whether the two boxes share any point (borders included).
    ///
    /// ```
    /// use citymesh_core::geo::GeoBbox;
    /// let a = GeoBbox::new(8.0, 49.0, 8.1, 49.1).unwrap();
    /// assert!(a.intersects(&GeoBbox::new(8.1, 49.1, 8.2, 49.2).unwrap()));
    /// assert!(!a.intersects(&GeoBbox::new(8.11, 49.0, 8.2, 49.1).unwrap()));
    /// ```
    pub fn intersects(&self, other: &GeoBbox) -> bool {
        self.min_lon <= other.max_lon
            && self.max_lon >= other.min_lon
            && self.min_lat <= other.max_lat
            && self.max_lat >= other.min_lat
    }

    /// Whether the two boxes share some area (not only a border).
    pub fn overlaps(&self, other: &GeoBbox) -> bool {
        self.min_lon < other.max_lon
            && self.max_lon > other.min_lon
            && self.min_lat < other.max_lat
            && self.max_lat > other.min_lat
    }

    /// The whole Web Mercator square: every longitude, latitudes to ±85.05°, as tile 0/0/0.
    pub fn world() -> Self {
        Self::from_ordered(-180.0, -MAX_MERCATOR_LAT, 180.0, MAX_MERCATOR_LAT)
    }

    /// The box grown by `margin` degrees on every side, clamped to the valid range.
    ///
    /// ```
    /// use citymesh_core::geo::GeoBbox;
    /// let b = GeoBbox::new(8.39, 49.04, 8.41, 49.06).unwrap().grown_by_degrees(0.01);
    /// assert_eq!(b.to_string(), "8.38,49.03,8.42,49.07");
    /// let edge = GeoBbox::new(179.5, 0.0, 180.0, 1.0).unwrap().grown_by_degrees(1.0);
    /// assert_eq!(edge.max_lon(), 180.0);
    /// ```
    pub fn grown_by_degrees(&self, margin: f64) -> Self {
        self.grown(margin, margin)
    }

    /// The box grown by `metres` on every side (converted to degrees at its centre), clamped to
    /// the valid range.
    pub fn grown_by_metres(&self, metres: f64) -> Self {
        let (lon, lat) = self.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        self.grown(metres / mx, metres / my)
    }

    fn grown(&self, dlon: f64, dlat: f64) -> Self {
        let (dlon, dlat) = (dlon.max(0.0), dlat.max(0.0));
        if !(dlon.is_finite() && dlat.is_finite()) {
            return *self;
        }
        Self {
            min_lon: (self.min_lon - dlon).max(-180.0),
            min_lat: (self.min_lat - dlat).max(-MAX_MERCATOR_LAT),
            max_lon: (self.max_lon + dlon).min(180.0),
            max_lat: (self.max_lat + dlat).min(MAX_MERCATOR_LAT),
        }
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &GeoBbox) -> Self {
        Self {
            min_lon: self.min_lon.min(other.min_lon),
            min_lat: self.min_lat.min(other.min_lat),
            max_lon: self.max_lon.max(other.max_lon),
            max_lat: self.max_lat.max(other.max_lat),
        }
    }
}

use super::LocalFrame;

impl FromStr for GeoBbox {
    type Err = BboxError;

    /// Parses `minLon,minLat,maxLon,maxLat`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 4 {
            return Err(BboxError::WrongCount(parts.len()));
        }
        let mut v = [0.0; 4];
        for (index, text) in parts.iter().enumerate() {
            v[index] = text.parse::<f64>().map_err(|_| BboxError::NotANumber {
                index,
                text: (*text).chars().take(40).collect(),
            })?;
        }
        Self::new(v[0], v[1], v[2], v[3])
    }
}

impl fmt::Display for GeoBbox {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{},{},{},{}",
            self.min_lon, self.min_lat, self.max_lon, self.max_lat
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case("8.39,49.04,8.41", BboxError::WrongCount(3))]
    #[case("8.39,49.04,x,49.06", BboxError::NotANumber { index: 2, text: "x".into() })]
    #[case("NaN,49.04,8.41,49.06", BboxError::NotFinite { index: 0, value: f64::NAN })]
    #[case("8.41,49.04,8.39,49.06", BboxError::InvertedLongitude { min: 8.41, max: 8.39 })]
    #[case("8.39,49.06,8.41,49.04", BboxError::InvertedLatitude { min: 49.06, max: 49.04 })]
    #[case("8.39,85.06,8.41,85.07", BboxError::LatitudeOutOfRange(85.06))]
    #[case("-181,49,8,49.1", BboxError::LongitudeOutOfRange(-181.0))]
    fn refuses_bad_boxes(#[case] text: &str, #[case] expected: BboxError) {
        let err = text.parse::<GeoBbox>().unwrap_err();
        // NaN != NaN, so compare the messages, which carry every field.
        assert_eq!(err.to_string(), expected.to_string());
    }

    #[test]
    fn parses_and_measures() {
        let b: GeoBbox = " 8.39, 49.04 ,8.41,49.06".parse().unwrap();
        assert_eq!(
            (b.min_lon(), b.min_lat(), b.max_lon(), b.max_lat()),
            (8.39, 49.04, 8.41, 49.06)
        );
        // 0.02 deg of longitude at 49.05 N is 1.46197 km and 0.02 deg of latitude 2.22421 km
        // (WGS84 radii of curvature at the centre).
        assert!((b.area_km2() - 3.25174).abs() < 1e-5, "{}", b.area_km2());
    }
}

//! A geographic region with a height range: what 3D Tiles calls a bounding region, and what a
//! scene's extent is.

use super::GeoBbox;

/// Metres per degree of latitude (a lower bound over the ellipsoid), for the slack in degrees.
const MIN_METRES_PER_DEGREE: f64 = 110_500.0;

/// A region: west, south, east, north in degrees, heights in metres above the ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub west: f64,
    pub south: f64,
    pub east: f64,
    pub north: f64,
    pub min_height: f64,
    pub max_height: f64,
}

impl Region {
    /// A box with a height range.
    pub fn of_bbox(b: &GeoBbox, min_height: f64, max_height: f64) -> Self {
        Self {
            west: b.min_lon(),
            south: b.min_lat(),
            east: b.max_lon(),
            north: b.max_lat(),
            min_height,
            max_height,
        }
    }

    /// The smallest region holding `points` (lon, lat, height), if there are any.
    pub fn of_points(points: impl IntoIterator<Item = (f64, f64, f64)>) -> Option<Self> {
        let mut r: Option<Region> = None;
        for (lon, lat, h) in points {
            let p = Region {
                west: lon,
                south: lat,
                east: lon,
                north: lat,
                min_height: h,
                max_height: h,
            };
            r = Some(r.map_or(p, |r| r.union(&p)));
        }
        r
    }

    /// The smallest region holding both.
    pub fn union(&self, o: &Region) -> Region {
        Region {
            west: self.west.min(o.west),
            south: self.south.min(o.south),
            east: self.east.max(o.east),
            north: self.north.max(o.north),
            min_height: self.min_height.min(o.min_height),
            max_height: self.max_height.max(o.max_height),
        }
    }

    /// Whether the point lies inside (borders included).
    pub fn contains(&self, lon: f64, lat: f64, h: f64) -> bool {
        (self.west..=self.east).contains(&lon)
            && (self.south..=self.north).contains(&lat)
            && (self.min_height..=self.max_height).contains(&h)
    }

    /// The region grown by `metres` on every side.
    pub fn grown(&self, metres: f64) -> Region {
        let lat = metres / MIN_METRES_PER_DEGREE;
        let cos = self.north.abs().max(self.south.abs()).to_radians().cos();
        let lon = lat / cos.max(1e-6);
        Region {
            west: self.west - lon,
            south: self.south - lat,
            east: self.east + lon,
            north: self.north + lat,
            min_height: self.min_height - metres,
            max_height: self.max_height + metres,
        }
    }

    /// As 3D Tiles writes a region: radians, then metres.
    pub fn to_radians(&self) -> [f64; 6] {
        [
            self.west.to_radians(),
            self.south.to_radians(),
            self.east.to_radians(),
            self.north.to_radians(),
            self.min_height,
            self.max_height,
        ]
    }
}

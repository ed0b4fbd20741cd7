//! The parameters of a procedural city (docs/method.md section 10), with their defaults and checks.

use crate::building::roof::RoofShape;

/// The kinds of block layout the generator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum LayoutType {
    /// Single houses on their own lots, pitched roofs.
    Detached,
    /// Terraces of houses sharing their side walls (so they share nodes and form groups).
    Row,
    /// A closed block around a courtyard (a polygon with a hole).
    Perimeter,
    /// A tower on a podium: an outline with two `building:part`s.
    Tower,
    /// Large flat-roofed halls.
    Industrial,
}

impl LayoutType {
    pub const ALL: [LayoutType; 5] = [
        LayoutType::Detached,
        LayoutType::Row,
        LayoutType::Perimeter,
        LayoutType::Tower,
        LayoutType::Industrial,
    ];

    /// The name used in query strings and in the `citymesh:layout` property.
    pub fn name(self) -> &'static str {
        match self {
            LayoutType::Detached => "detached",
            LayoutType::Row => "row",
            LayoutType::Perimeter => "perimeter",
            LayoutType::Tower => "tower",
            LayoutType::Industrial => "industrial",
        }
    }

    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|l| l.name() == s)
    }

    /// The smallest block side (metres) the layout fits in.
    pub fn min_block(self) -> f64 {
        match self {
            LayoutType::Detached | LayoutType::Row => 22.0,
            LayoutType::Perimeter => 40.0,
            LayoutType::Tower => 34.0,
            LayoutType::Industrial => 45.0,
        }
    }
}

/// Everything that decides a procedural city. The same parameters give the same city.
#[derive(Debug, Clone, PartialEq)]
pub struct ProceduralParams {
    pub seed: u64,
    /// Size of the area, metres east-west and north-south.
    pub width: f64,
    pub height: f64,
    /// The area is split into about 2^complexity blocks.
    pub complexity: u32,
    /// Relative weight of each layout type (0 = never).
    pub layouts: [f64; 5],
    /// Relative weight of each roof shape, in [`RoofShape::ALL`] order, where the layout does not
    /// force flat roofs (towers and industrial halls do).
    pub roofs: [f64; RoofShape::COUNT],
    /// Where the area's centre is placed (degrees).
    pub lon: f64,
    pub lat: f64,
}

/// The default location: Karlsruhe palace.
pub const DEFAULT_LON: f64 = 8.4044;
pub const DEFAULT_LAT: f64 = 49.0135;

impl Default for ProceduralParams {
    fn default() -> Self {
        Self {
            seed: 1,
            width: 1000.0,
            height: 1000.0,
            complexity: 6,
            layouts: [3.0, 2.0, 2.0, 1.0, 1.0],
            // The paper's eight; the other shapes only when asked.
            roofs: [
                3.0, 4.0, 3.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                0.0, 0.0, 0.0, 0.0,
            ],
            lon: DEFAULT_LON,
            lat: DEFAULT_LAT,
        }
    }
}

/// Why parameters were refused; each message says what to fix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamError {
    #[error("{name} must be between {min} and {max} metres, got {value}")]
    Size {
        name: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    #[error("complexity must be a whole number from 0 to {max}, got {value}")]
    Complexity { value: u32, max: u32 },
    #[error("weight of '{name}' must be a finite number >= 0, got {value}")]
    Weight { name: String, value: f64 },
    #[error(
        "the {what} weights add up to {sum}, which is not a finite number: use smaller weights"
    )]
    WeightSum { what: &'static str, sum: f64 },
    #[error("lon must be within -180..180 and lat within -85..85, got {lon}, {lat}")]
    Location { lon: f64, lat: f64 },
}

/// The largest side of a procedural area, metres.
pub const MAX_SIDE: f64 = 5000.0;
/// The smallest side, metres.
pub const MIN_SIDE: f64 = 50.0;
/// The deepest subdivision.
pub const MAX_COMPLEXITY: u32 = 12;

impl ProceduralParams {
    pub fn validate(&self) -> Result<(), ParamError> {
        for (name, value) in [("width", self.width), ("height", self.height)] {
            if !(MIN_SIDE..=MAX_SIDE).contains(&value) {
                return Err(ParamError::Size {
                    name,
                    value,
                    min: MIN_SIDE,
                    max: MAX_SIDE,
                });
            }
        }
        if self.complexity > MAX_COMPLEXITY {
            return Err(ParamError::Complexity {
                value: self.complexity,
                max: MAX_COMPLEXITY,
            });
        }
        let names = LayoutType::ALL
            .iter()
            .map(|l| l.name())
            .zip(self.layouts)
            .chain(RoofShape::ALL.iter().map(|r| r.tag()).zip(self.roofs));
        for (name, value) in names {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ParamError::Weight {
                    name: name.to_owned(),
                    value,
                });
            }
        }
        for (what, weights) in [("layout", &self.layouts[..]), ("roof", &self.roofs[..])] {
            let sum: f64 = weights.iter().sum();
            if !sum.is_finite() {
                return Err(ParamError::WeightSum { what, sum });
            }
        }
        if !(self.lon.is_finite()
            && self.lat.is_finite()
            && (-180.0..=180.0).contains(&self.lon)
            && (-85.0..=85.0).contains(&self.lat))
        {
            return Err(ParamError::Location {
                lon: self.lon,
                lat: self.lat,
            });
        }
        Ok(())
    }
}

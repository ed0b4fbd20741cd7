//! How a pitched roof is laid over its footprint (docs/method.md section 6.7): the paper's
//! virtual rectangle, or the footprint's straight skeleton.

use super::axes::RoofAxes;
use super::footprint::Footprint;
use super::roof::RoofShape;

/// Under [`RoofMethod::Auto`], a footprint without courtyards that fills at least this share of
/// its virtual rectangle keeps the rectangle: its roof is the paper's, cropped by the outline.
pub const NEAR_RECTANGLE_FILL: f64 = 0.9;

/// Which construction draws hipped, gabled and pyramidal roofs. The other shapes always use the
/// virtual rectangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum RoofMethod {
    /// The straight skeleton for footprints with courtyards or that fill less than
    /// [`NEAR_RECTANGLE_FILL`] of their virtual rectangle (L, T, U, and other complex
    /// outlines); the virtual rectangle for the rest.
    #[default]
    Auto,
    /// The paper's virtual rectangle everywhere.
    Rectangle,
    /// The straight skeleton for every hipped, gabled and pyramidal roof.
    Skeleton,
}

impl RoofMethod {
    /// The name used by flags and in cache keys.
    pub fn name(self) -> &'static str {
        match self {
            RoofMethod::Auto => "auto",
            RoofMethod::Rectangle => "rectangle",
            RoofMethod::Skeleton => "skeleton",
        }
    }

    /// Whether a `shape` roof over `footprint` (whose virtual rectangle `axes` gives) is built
    /// from the straight skeleton.
    pub fn uses_skeleton(self, shape: RoofShape, footprint: &Footprint, axes: &RoofAxes) -> bool {
        if !takes_skeleton(shape) {
            return false;
        }
        match self {
            RoofMethod::Rectangle => false,
            RoofMethod::Skeleton => true,
            RoofMethod::Auto => !is_near_rectangle(footprint, axes),
        }
    }
}

/// The shapes the straight skeleton draws.
pub fn takes_skeleton(shape: RoofShape) -> bool {
    matches!(
        shape,
        RoofShape::Hipped | RoofShape::Gabled | RoofShape::Pyramidal
    )
}

/// Whether a footprint has no courtyard and fills at least [`NEAR_RECTANGLE_FILL`] of its
/// virtual rectangle.
pub fn is_near_rectangle(footprint: &Footprint, axes: &RoofAxes) -> bool {
    footprint.holes.is_empty() && footprint.area() >= NEAR_RECTANGLE_FILL * 4.0 * axes.rx * axes.ry
}

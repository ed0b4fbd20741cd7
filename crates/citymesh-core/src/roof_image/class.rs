//! The classes the roof classifier predicts: the paper's three (flat, gabled, hipped).

use crate::building::roof::RoofShape;

/// A roof class of the classifier, in the order of the model's outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RoofClass {
    Flat,
    Gabled,
    Hipped,
}

impl RoofClass {
    /// All classes, in the order of the model's outputs.
    pub const ALL: [RoofClass; 3] = [RoofClass::Flat, RoofClass::Gabled, RoofClass::Hipped];

    /// The class name, which is also the OSM `roof:shape` value.
    pub fn name(self) -> &'static str {
        self.shape().tag()
    }

    /// The class with this name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The roof shape citymesh builds for this class.
    pub fn shape(self) -> RoofShape {
        match self {
            RoofClass::Flat => RoofShape::Flat,
            RoofClass::Gabled => RoofShape::Gabled,
            RoofClass::Hipped => RoofShape::Hipped,
        }
    }

    /// The class a roof shape is trained and evaluated as: pyramidal roofs are hipped roofs over a
    /// square (four facets meeting at a point) and count as hipped; the other shapes (skillion,
    /// half-hipped, gambrel, mansard, domes...) are not one of the three and are left out.
    pub fn of_shape(shape: RoofShape) -> Option<Self> {
        match shape {
            RoofShape::Flat => Some(RoofClass::Flat),
            RoofShape::Gabled => Some(RoofClass::Gabled),
            RoofShape::Hipped | RoofShape::Pyramidal => Some(RoofClass::Hipped),
            _ => None,
        }
    }

    /// The index of this class in the model's outputs.
    pub fn index(self) -> usize {
        self as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_match_osm_tags() {
        for c in RoofClass::ALL {
            assert_eq!(RoofClass::from_name(c.name()), Some(c));
            assert_eq!(RoofShape::from_tag(c.name()), Some(c.shape()));
            assert_eq!(RoofClass::of_shape(c.shape()), Some(c));
        }
        assert_eq!(
            [RoofClass::Flat, RoofClass::Gabled, RoofClass::Hipped].map(RoofClass::index),
            [0, 1, 2]
        );
        assert_eq!(RoofClass::of_shape(RoofShape::Mansard), None);
    }
}

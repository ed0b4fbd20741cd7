//! From parsed tags to the numbers the generator needs: roof shape, heights and colours, with the
//! fallbacks of docs/method.md section 6 (all defaults live in [`super::defaults`]). Each fallback
//! taken is recorded, so scene statistics can say how much came from tags.

use super::defaults::{
    DEFAULT_FLAT_ROOF_COLOUR, DEFAULT_PITCH_DEGREES, DEFAULT_PITCHED_ROOF_COLOUR,
    DEFAULT_ROOF_SHARE_OF_HEIGHT, DEFAULT_WALL_COLOUR, LEVEL_HEIGHT, MIN_WALL_HEIGHT,
    default_levels, roof_colour_for_material, wall_colour_for_material,
};
use super::roof::RoofShape;
use super::tags::{BuildingTags, ShapeTag};
use crate::mesh::Rgb;

/// Where the roof shape came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ShapeSource {
    /// `roof:shape` names a shape citymesh draws.
    Tag,
    /// No `roof:shape`: the default (flat).
    Default,
    /// `roof:shape` names no shape citymesh draws: rendered flat.
    Unsupported,
}

/// Where the total height came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum HeightSource {
    /// `height`.
    Tag,
    /// `building:levels` (and `roof:levels`) times the level height.
    Levels,
    /// The default number of levels for the building type.
    TypeDefault,
}

/// Where the roof height came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RoofHeightSource {
    /// Flat roofs have none.
    None,
    Tag,
    Angle,
    Levels,
    /// The default pitch.
    DefaultPitch,
}

/// The generator's inputs for one building, before the ground is known.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingParams {
    pub shape: RoofShape,
    pub shape_source: ShapeSource,
    /// Total height above the ground (h_total), metres.
    pub height: f64,
    pub height_source: HeightSource,
    /// Height of the floor above the ground (h_min), metres.
    pub min_height: f64,
    /// Roof height from eaves to top (h_roof), metres.
    pub roof_height: f64,
    pub roof_height_source: RoofHeightSource,
    pub wall_colour: Rgb,
    pub roof_colour: Rgb,
}

impl BuildingParams {
    /// The parameters of a building whose roof rises over a horizontal run of `run` metres (from
    /// eaves to top, see [`super::roof_surface::RoofSurface::run`]).
    pub fn new(tags: &BuildingTags, run: f64) -> Self {
        let (shape, shape_source) = match &tags.roof_shape {
            Some(ShapeTag::Known(s)) => (*s, ShapeSource::Tag),
            Some(ShapeTag::Unsupported(_)) => (RoofShape::Flat, ShapeSource::Unsupported),
            Some(ShapeTag::Missing) | None => (RoofShape::Flat, ShapeSource::Default),
        };
        let min_height = tags
            .min_height
            .or_else(|| tags.min_level.map(|l| l * LEVEL_HEIGHT))
            .unwrap_or(0.0);

        let (mut roof_height, mut roof_height_source) = if shape == RoofShape::Flat {
            (0.0, RoofHeightSource::None)
        } else if let Some(h) = tags.roof_height {
            (h, RoofHeightSource::Tag)
        } else if let Some(a) = tags.roof_angle {
            (a.to_radians().tan() * run, RoofHeightSource::Angle)
        } else if let Some(l) = tags.roof_levels.filter(|l| *l > 0.0) {
            (l * LEVEL_HEIGHT, RoofHeightSource::Levels)
        } else {
            (
                DEFAULT_PITCH_DEGREES.to_radians().tan() * run,
                RoofHeightSource::DefaultPitch,
            )
        };

        // A default roof is capped by the body: half the tagged height, or the walls' height
        // from levels (tagged or by building type).
        if roof_height_source == RoofHeightSource::DefaultPitch {
            let body = match tags.height.filter(|h| *h > min_height) {
                Some(h) => (h - min_height) * DEFAULT_ROOF_SHARE_OF_HEIGHT,
                None => {
                    tags.levels
                        .filter(|l| *l > 0.0)
                        .unwrap_or_else(|| default_levels(&tags.building_type))
                        * LEVEL_HEIGHT
                }
            };
            roof_height = roof_height.min(body);
        }
        let (height, height_source) = if let Some(h) = tags.height.filter(|h| *h > min_height) {
            (h, HeightSource::Tag)
        } else if let Some(l) = tags.levels.filter(|l| *l > 0.0) {
            (l * LEVEL_HEIGHT + roof_height, HeightSource::Levels)
        } else {
            (
                min_height + default_levels(&tags.building_type) * LEVEL_HEIGHT + roof_height,
                HeightSource::TypeDefault,
            )
        };
        // The walls keep at least MIN_WALL_HEIGHT; a roof taller than that allows is cut down.
        let room = (height - min_height - MIN_WALL_HEIGHT).max(0.0);
        if roof_height > room {
            roof_height = room;
        }
        if roof_height <= 0.0 && shape != RoofShape::Flat {
            roof_height = 0.0;
            roof_height_source = RoofHeightSource::None;
        }
        let (height, min_height) = if height > min_height {
            (height, min_height)
        } else {
            // min_height at or above the height: the building keeps its walls from the ground.
            (height.max(MIN_WALL_HEIGHT), 0.0)
        };

        let wall_colour = tags
            .building_colour
            .or_else(|| {
                tags.building_material
                    .as_deref()
                    .and_then(wall_colour_for_material)
            })
            .unwrap_or(DEFAULT_WALL_COLOUR);
        let roof_colour = tags
            .roof_colour
            .or_else(|| {
                tags.roof_material
                    .as_deref()
                    .and_then(roof_colour_for_material)
            })
            .unwrap_or(if shape == RoofShape::Flat {
                DEFAULT_FLAT_ROOF_COLOUR
            } else {
                DEFAULT_PITCHED_ROOF_COLOUR
            });
        Self {
            shape,
            shape_source,
            height,
            height_source,
            min_height,
            roof_height,
            roof_height_source,
            wall_colour,
            roof_colour,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osm::Tags;

    fn params(tags: &[(&str, &str)], run: f64) -> BuildingParams {
        let tags: Tags = tags
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        BuildingParams::new(&BuildingTags::read(&tags), run)
    }

    #[test]
    fn a_default_roof_never_dwarfs_its_body() {
        let pitch = 30f64.to_radians().tan();
        // A 2-level hall 45 m across: the default pitch would give 26 m of roof on 6 m of walls;
        // the walls' height caps it.
        let hall = params(
            &[
                ("building", "industrial"),
                ("building:levels", "2"),
                ("roof:shape", "gabled"),
            ],
            45.0,
        );
        assert_eq!(hall.roof_height, 6.0);
        assert_eq!(hall.height, 12.0);
        // With a height, at most half of it.
        let tall = params(
            &[
                ("building", "yes"),
                ("height", "10"),
                ("roof:shape", "hipped"),
            ],
            45.0,
        );
        assert_eq!(tall.roof_height, 5.0);
        // A small house keeps its 30 degrees.
        let house = params(
            &[
                ("building", "house"),
                ("building:levels", "2"),
                ("roof:shape", "gabled"),
            ],
            4.0,
        );
        assert!((house.roof_height - 4.0 * pitch).abs() < 1e-12);
        // A tagged roof height is the mapper's word, never capped.
        let tagged = params(
            &[
                ("building", "yes"),
                ("building:levels", "1"),
                ("roof:height", "8"),
                ("roof:shape", "gabled"),
            ],
            45.0,
        );
        assert_eq!(tagged.roof_height, 8.0);
    }

    #[test]
    fn heights_follow_the_fallback_chain() {
        let p = params(
            &[
                ("building", "house"),
                ("height", "12"),
                ("roof:height", "4"),
                ("roof:shape", "gabled"),
            ],
            5.0,
        );
        assert_eq!((p.height, p.roof_height), (12.0, 4.0));
        assert_eq!(p.height_source, HeightSource::Tag);
        // Levels: 3 x 3 m plus the roof from its angle (45 degrees over a 5 m run).
        let p = params(
            &[
                ("building", "house"),
                ("building:levels", "3"),
                ("roof:angle", "45"),
                ("roof:shape", "hipped"),
            ],
            5.0,
        );
        assert!((p.roof_height - 5.0).abs() < 1e-12);
        assert!((p.height - 14.0).abs() < 1e-12);
        assert_eq!(p.roof_height_source, RoofHeightSource::Angle);
        // Nothing: a house has 2 levels, a flat roof has no height.
        let p = params(&[("building", "house")], 5.0);
        assert_eq!(
            (p.height, p.roof_height, p.shape),
            (6.0, 0.0, RoofShape::Flat)
        );
        assert_eq!(
            (p.shape_source, p.height_source),
            (ShapeSource::Default, HeightSource::TypeDefault)
        );
        // roof:levels, and the default pitch.
        let p = params(
            &[
                ("building", "yes"),
                ("roof:levels", "1"),
                ("roof:shape", "gabled"),
                ("building:levels", "2"),
            ],
            5.0,
        );
        assert_eq!((p.roof_height, p.height), (3.0, 9.0));
        let p = params(&[("building", "garage"), ("roof:shape", "skillion")], 2.0);
        assert!((p.roof_height - 2.0 * 30f64.to_radians().tan()).abs() < 1e-12);
    }

    #[test]
    fn roofs_leave_room_for_walls_and_odd_shapes_render_flat() {
        let p = params(
            &[
                ("building", "yes"),
                ("height", "4"),
                ("roof:height", "9"),
                ("roof:shape", "gabled"),
            ],
            5.0,
        );
        assert_eq!(p.roof_height, 4.0 - MIN_WALL_HEIGHT);
        let p = params(&[("building", "yes"), ("roof:shape", "zakomar")], 5.0);
        assert_eq!(
            (p.shape, p.shape_source),
            (RoofShape::Flat, ShapeSource::Unsupported)
        );
        let p = params(
            &[("building", "yes"), ("roof:shape", "quadruple_saltbox")],
            5.0,
        );
        assert_eq!(
            (p.shape, p.shape_source),
            (RoofShape::QuadrupleSaltbox, ShapeSource::Tag)
        );
        let p = params(
            &[
                ("building:part", "yes"),
                ("height", "20"),
                ("min_height", "12"),
            ],
            5.0,
        );
        assert_eq!((p.min_height, p.height), (12.0, 20.0));
        let p = params(
            &[
                ("building", "yes"),
                ("building:levels", "4"),
                ("building:min_level", "1"),
            ],
            5.0,
        );
        assert_eq!((p.min_height, p.height), (3.0, 12.0));
    }

    #[test]
    fn colours_from_tags_then_materials_then_defaults() {
        let p = params(
            &[
                ("building", "yes"),
                ("building:colour", "red"),
                ("roof:material", "slate"),
            ],
            5.0,
        );
        assert_eq!(p.wall_colour, Rgb(255, 0, 0));
        assert_eq!(p.roof_colour, Rgb(0x50, 0x58, 0x60));
        let p = params(&[("building", "yes"), ("building:material", "brick")], 5.0);
        assert_eq!(p.wall_colour, Rgb(0xa8, 0x5a, 0x44));
        assert_eq!(p.roof_colour, DEFAULT_FLAT_ROOF_COLOUR);
    }
}

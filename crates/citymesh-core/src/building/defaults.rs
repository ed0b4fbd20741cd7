//! Every default citymesh assumes when OSM tags are silent, in one place
//! (docs/method.md section 6).
//!
//! | value | default |
//! |---|---|
//! | level height | 3.0 m per `building:levels`, `roof:levels`, `building:min_level` |
//! | levels by building type | see [`default_levels`] (2 when the type is unknown) |
//! | roof shape | flat |
//! | roof pitch | 30 degrees, when neither `roof:height`, `roof:angle` nor `roof:levels` is given |
//! | lowest wall under a roof | 0.5 m: taller roofs are cut down |
//! | half-hipped HE, gambrel GP, mansard MP | 0.7 each |
//! | wall colour | by `building:material`, else plaster `#e8e0d0` |
//! | roof colour | by `roof:material`, else grey `#8a8a8a` (flat) or tile red `#a0522d` (pitched) |

use crate::mesh::Rgb;

/// Height of one storey in metres (the paper suggests 3 to 4 m).
pub const LEVEL_HEIGHT: f64 = 3.0;

/// The lowest walls citymesh builds under a roof, metres: a roof taller than the building allows
/// is cut down to leave this much wall.
pub const MIN_WALL_HEIGHT: f64 = 0.5;

/// Roof pitch in degrees when nothing says how high a pitched roof is.
pub const DEFAULT_PITCH_DEGREES: f64 = 30.0;

/// A default roof (from [`DEFAULT_PITCH_DEGREES`], no roof tag) is at most this share of the
/// building's height when `height` is tagged, and at most its walls' height otherwise, so a wide
/// footprint's default roof never dwarfs the body it stands on.
pub const DEFAULT_ROOF_SHARE_OF_HEIGHT: f64 = 0.5;

/// The half-hipped parameter HE: the share of the end walls that is hipped
/// (docs/method.md section 6).
pub const HALF_HIPPED_HE: f64 = 0.7;
/// The gambrel parameter GP: where the slope breaks, from the ridge (docs/method.md section 6).
pub const GAMBREL_GP: f64 = 0.7;
/// The mansard parameter MP (docs/method.md section 6).
pub const MANSARD_MP: f64 = 0.7;

/// The largest height citymesh believes (the tallest building is 828 m).
pub const MAX_HEIGHT: f64 = 1000.0;

/// Storeys of a building of this `building=*` type when `building:levels` is missing.
pub fn default_levels(building_type: &str) -> f64 {
    match building_type {
        "garage" | "garages" | "carport" | "shed" | "hut" | "cabin" | "kiosk" | "roof"
        | "toilets" | "bunker" | "transformer_tower" | "service" | "greenhouse"
        | "farm_auxiliary" | "barn" | "stable" => 1.0,
        "retail" | "supermarket" | "industrial" | "warehouse" | "manufacture" | "sports_hall"
        | "bungalow" => 1.0,
        "house" | "detached" | "semidetached_house" | "terrace" | "farm" | "yes"
        | "static_caravan" => 2.0,
        "residential" | "commercial" | "school" | "kindergarten" | "public" | "civic"
        | "church" | "chapel" | "train_station" | "university" | "college" => 3.0,
        "apartments" | "office" | "hotel" | "hospital" | "dormitory" => 4.0,
        _ => 2.0,
    }
}

/// Wall colour for a `building:material` value.
pub fn wall_colour_for_material(material: &str) -> Option<Rgb> {
    Some(match material {
        "brick" => Rgb(0xa8, 0x5a, 0x44),
        "concrete" | "cement_block" => Rgb(0xb4, 0xb0, 0xa8),
        "glass" | "mirror" => Rgb(0x9c, 0xc4, 0xd8),
        "metal" | "steel" | "aluminium" => Rgb(0xa8, 0xac, 0xb0),
        "wood" | "timber_framing" => Rgb(0x9a, 0x6e, 0x46),
        "stone" | "sandstone" | "granite" | "limestone" => Rgb(0xc8, 0xb8, 0x98),
        "plaster" | "render" => Rgb(0xe8, 0xe0, 0xd0),
        "plastic" | "vinyl" => Rgb(0xe0, 0xe0, 0xd8),
        _ => return None,
    })
}

/// Roof colour for a `roof:material` value.
pub fn roof_colour_for_material(material: &str) -> Option<Rgb> {
    Some(match material {
        "roof_tiles" | "tile" | "tiles" | "clay" => Rgb(0xa0, 0x52, 0x2d),
        "concrete" => Rgb(0x9a, 0x9a, 0x94),
        "metal" | "tin" | "steel" | "aluminium" => Rgb(0x80, 0x88, 0x90),
        "copper" => Rgb(0x6a, 0xa8, 0x8c),
        "slate" | "stone" => Rgb(0x50, 0x58, 0x60),
        "tar_paper" | "asphalt" | "bitumen" | "eternit" => Rgb(0x48, 0x48, 0x48),
        "gravel" | "pebblestone" => Rgb(0xa8, 0xa4, 0x98),
        "grass" | "plants" => Rgb(0x6a, 0x8a, 0x48),
        "glass" => Rgb(0x9c, 0xc4, 0xd8),
        "wood" | "thatch" => Rgb(0x8a, 0x6a, 0x40),
        "solar_panels" => Rgb(0x30, 0x38, 0x58),
        _ => return None,
    })
}

pub const DEFAULT_WALL_COLOUR: Rgb = Rgb(0xe8, 0xe0, 0xd0);
pub const DEFAULT_FLAT_ROOF_COLOUR: Rgb = Rgb(0x8a, 0x8a, 0x8a);
pub const DEFAULT_PITCHED_ROOF_COLOUR: Rgb = Rgb(0xa0, 0x52, 0x2d);

//! The choices a scene's buildings are generated under, beyond their data: where `height` is
//! counted from, and how pitched roofs are laid over footprints.

use super::height_base::HeightBase;
use super::roof_method::RoofMethod;

/// How buildings are generated, as the server or command line was asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct BuildingRules {
    pub heights: HeightBase,
    pub roof_method: RoofMethod,
}

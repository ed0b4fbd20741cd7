//! Value options shared by `scene`, `serve` and `export`: how vertices are encoded, where
//! `height` counts from, how pitched roofs are laid.

/// `--roof-method`: how pitched roofs are laid over footprints (docs/method.md section 6.7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum RoofMethodArg {
    /// The straight skeleton for footprints with courtyards or filling less than 90 % of their
    /// virtual rectangle; the virtual rectangle for the others.
    #[default]
    Auto,
    /// The paper's virtual rectangle for every roof.
    Rectangle,
    /// The straight skeleton for every hipped, gabled and pyramidal roof.
    Skeleton,
}

impl From<RoofMethodArg> for citymesh_core::building::RoofMethod {
    fn from(m: RoofMethodArg) -> Self {
        match m {
            RoofMethodArg::Auto => Self::Auto,
            RoofMethodArg::Rectangle => Self::Rectangle,
            RoofMethodArg::Skeleton => Self::Skeleton,
        }
    }
}

/// `--height-base`: the ground a building's `height` is counted from (docs/method.md section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HeightBaseArg {
    /// The lowest ground along the outline, as OpenStreetMap's Simple 3D Buildings defines.
    #[default]
    Lowest,
    /// The highest ground along the outline (the paper's Figure 5): taller on slopes.
    Highest,
}

impl From<HeightBaseArg> for citymesh_core::building::HeightBase {
    fn from(h: HeightBaseArg) -> Self {
        match h {
            HeightBaseArg::Lowest => Self::LowestGround,
            HeightBaseArg::Highest => Self::HighestGround,
        }
    }
}

/// `--encoding` of `citymesh scene`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum EncodingArg {
    Plain,
    Quantized,
    Meshopt,
}

impl From<EncodingArg> for citymesh_core::mesh::Encoding {
    fn from(e: EncodingArg) -> Self {
        match e {
            EncodingArg::Plain => Self::Plain,
            EncodingArg::Quantized => Self::Quantized,
            EncodingArg::Meshopt => Self::Meshopt,
        }
    }
}

/// The value of an optional `--bbox` flag (minLon,minLat,maxLon,maxLat), or an error naming it.
pub fn bbox_arg(text: Option<&String>) -> anyhow::Result<Option<citymesh_core::geo::GeoBbox>> {
    text.map(|t| {
        t.parse::<citymesh_core::geo::GeoBbox>()
            .map_err(|e| anyhow::anyhow!("--bbox {t}: {e}"))
    })
    .transpose()
}

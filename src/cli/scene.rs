//! Options of `citymesh scene`: one GLB from OSM files, in the foreground.

use super::*;
use clap::Parser;
use std::path::PathBuf;

/// Options of `citymesh scene`.
#[derive(Debug, Clone, Parser)]
pub struct SceneArgs {
    /// OSM data: OSM PBF, OSM XML or Overpass JSON, optionally gzipped (repeat for several).
    #[arg(long, required = true)]
    pub osm: Vec<PathBuf>,

    /// Directory with SRTM .hgt files (searched recursively); missing ones leave the ground flat
    /// at 0 m there, with a warning.
    #[arg(long, default_value = "data/dem")]
    pub dem_dir: PathBuf,

    /// The area as minLon,minLat,maxLon,maxLat: buildings are cut at its border, as `/scene`
    /// does. Default: every building whole, on the ground of their extent.
    #[arg(long)]
    pub bbox: Option<String>,

    /// The GLB file to write.
    #[arg(long, short)]
    pub out: PathBuf,

    /// How the GLB stores vertices: plain, quantized or meshopt.
    #[arg(long, value_enum, default_value_t = EncodingArg::Plain)]
    pub encoding: EncodingArg,

    /// Also write the scene's figures (buildings, roofs, ground, bytes, timings) as JSON here.
    #[arg(long)]
    pub stats: Option<PathBuf>,

    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings) or `highest` (the paper's rule).
    #[arg(long, value_enum, default_value_t = HeightBaseArg::Lowest)]
    pub height_base: HeightBaseArg,

    /// How hipped, gabled and pyramidal roofs are laid over footprints: `auto` (the straight
    /// skeleton for complex footprints, the virtual rectangle for near-rectangular ones),
    /// `rectangle` (the paper's, everywhere) or `skeleton` (everywhere).
    #[arg(long, value_enum, default_value_t = RoofMethodArg::Auto)]
    pub roof_method: RoofMethodArg,
}

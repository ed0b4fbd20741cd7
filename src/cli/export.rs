//! Options of `citymesh export`: a static 3D Tiles or XYZ tree.

use super::*;
use clap::Parser;

/// Options of `citymesh export`.
#[derive(Debug, Clone, Parser)]
pub struct ExportArgs {
    /// The area as minLon,minLat,maxLon,maxLat (the 3D Tiles region; the XYZ tiles covering it).
    #[arg(long)]
    pub bbox: String,

    /// Where to write the tree: a directory (created if missing) or `file://` URL, or an
    /// S3-compatible object store as `s3://BUCKET/PREFIX` (credentials, region and endpoint from
    /// the usual `AWS_*` variables: `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_REGION`,
    /// `AWS_ENDPOINT_URL` for a store other than Amazon's, `AWS_ALLOW_HTTP=true` for plain
    /// HTTP). Files already there are kept: a rerun resumes.
    #[arg(long, short)]
    pub out: String,

    /// `3dtiles` (as `/3dtiles/tileset.json` serves it) or `xyz`.
    #[arg(long, value_enum, default_value_t = ExportFormat::Tiles3d)]
    pub format: ExportFormat,

    /// How a 3D Tiles tileset lists its tiles: `explicit` (every tile written out) or
    /// `implicit` (a quadtree and its binary subtree), as `?tiling=` serves them.
    #[arg(long, value_enum, default_value_t = TilingArg::Explicit)]
    pub tiling: TilingArg,

    /// XYZ zoom levels, `A-B` or `A` (default 16).
    #[arg(long)]
    pub zooms: Option<String>,

    /// How GLBs store vertices (default: meshopt for 3D Tiles, plain for XYZ, as served).
    #[arg(long, value_enum)]
    pub encoding: Option<EncodingArg>,

    /// Tiles generated at once (default: the machine's cores).
    #[arg(long)]
    pub workers: Option<usize>,

    /// No progress bar or summary.
    #[arg(long)]
    pub quiet: bool,

    /// Where the data comes from, as for `serve` (--osm, --dem-dir, --cache-db, Overpass...).
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// `--format` of `citymesh export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// 3D Tiles 1.1.
    #[value(name = "3dtiles")]
    Tiles3d,
    /// XYZ GLB tiles.
    Xyz,
}

/// `--tiling` of `citymesh export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TilingArg {
    Explicit,
    Implicit,
}

impl From<TilingArg> for citymesh_core::tiles3d::Tiling {
    fn from(t: TilingArg) -> Self {
        match t {
            TilingArg::Explicit => Self::Explicit,
            TilingArg::Implicit => Self::Implicit,
        }
    }
}

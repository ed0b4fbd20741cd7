//! Options of `citymesh export`: a static 3D Tiles or XYZ tree.

use super::*;
use clap::Parser;

/// Options of `citymesh export`.
#[derive(Debug, Clone, Parser)]
pub struct ExportArgs {
    /// Only this area, as minLon,minLat,maxLon,maxLat, of any size: for 3D Tiles the world tree
    /// over the data tiles it meets, for XYZ the tiles covering it. Without it, everything the
    /// data holds: the world tileset `/3dtiles/tileset.json` serves, or the XYZ tiles over
    /// every data tile.
    #[arg(long)]
    pub bbox: Option<String>,

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

    /// How the 3D Tiles tileset lists its tiles: `explicit` only (the world tileset, in nested
    /// tileset files; an implicit tileset of a box is served by
    /// `/3dtiles/tileset.json?bbox=...&tiling=implicit`).
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

    /// Seconds a unit of work stays this exporter's without word from it: another exporter on
    /// the same database (`--database-url`) takes over a killed one's units after this long.
    #[arg(long, default_value_t = 30.0)]
    pub lease_s: f64,

    /// Also write what the run did as JSON to this file (files, written, kept, scenes
    /// generated, bytes, seconds).
    #[arg(long)]
    pub report: Option<std::path::PathBuf>,

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

impl ExportArgs {
    /// `--workers`, else the machine's cores.
    pub fn worker_count(&self) -> usize {
        self.workers
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from))
            .max(1)
    }
}

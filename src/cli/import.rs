//! Options of `citymesh import`: OSM files into the data-tile store.

use clap::Parser;
use std::path::PathBuf;

/// Options of `citymesh import`.
#[derive(Debug, Clone, Parser)]
pub struct ImportArgs {
    /// The OSM files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,

    /// SQLite file to write into (the one `serve --cache-db` uses).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

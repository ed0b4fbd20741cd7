//! Options of `citymesh import`: OSM files into the data-tile store.

use clap::Parser;
use std::path::PathBuf;

/// Options of `citymesh import`.
#[derive(Debug, Clone, Parser)]
pub struct ImportArgs {
    /// The OSM files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,

    /// The database to write into (the one `serve` uses): on PostgreSQL, running replicas are
    /// told which areas changed and drop what they hold of them.
    #[command(flatten)]
    pub database: super::DatabaseArgs,

    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

//! Options of `citymesh import`: OSM files into the data-tile store.

use clap::Parser;
use std::path::PathBuf;

/// Options of `citymesh import`.
#[derive(Debug, Clone, Parser)]
pub struct ImportArgs {
    /// The OSM files.
    #[arg(required_unless_present = "changes")]
    pub files: Vec<PathBuf>,

    /// Apply a change file (osmChange, `.osc` or `.osc.gz`) to the imported data instead: the
    /// buildings it touches are rebuilt, and the generated tiles over them dropped. Files
    /// from a replication feed are better followed with `citymesh replicate`, which also
    /// records the sequence number.
    #[arg(long, conflicts_with = "files")]
    pub changes: Option<PathBuf>,

    /// The database to write into (the one `serve` uses): on PostgreSQL, running replicas are
    /// told which areas changed and drop what they hold of them.
    #[command(flatten)]
    pub database: super::DatabaseArgs,

    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,

    /// Memory the import stays within, in MB (at least 16): a quarter caches node locations,
    /// a quarter groups records into data tiles. The file's size does not change what it
    /// needs; more makes a large import faster.
    #[arg(long, env = "CITYMESH_IMPORT_MEMORY_MB", default_value_t = crate::source::data_tiles::import::DEFAULT_MEMORY_MB,
          value_parser = clap::value_parser!(u64).range(16..))]
    pub memory_mb: u64,

    /// Where temporary files go: node locations (16 bytes per node of a PBF file) and records
    /// on their way to their data tiles (about the size of the store). The system's temporary
    /// directory when not given.
    #[arg(long, env = "CITYMESH_IMPORT_TEMP_DIR")]
    pub temp_dir: Option<PathBuf>,
}

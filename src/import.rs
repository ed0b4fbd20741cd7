//! `citymesh import FILE...`: OSM files into the data-tile store (`crate::source::data_tiles`),
//! then the stored tiles generated from data that changed are dropped (`crate::cache`). Run it
//! while the server is stopped, or restart the server after it: a running server keeps the data
//! it already parsed in memory.

use crate::cache::TileStore;
use crate::cache::invalidation::drop_stored;
use crate::db;
use crate::source::data_tiles::OsmTileStore;
use crate::source::data_tiles::import::{ImportReport, import_files};
use anyhow::Context;
use std::path::PathBuf;

/// Imports the files into the database at `cache_db`. `quiet` hides the progress bars.
pub async fn import(
    files: &[PathBuf],
    cache_db: &str,
    quiet: bool,
) -> anyhow::Result<ImportReport> {
    let pool = db::open(cache_db)
        .await
        .with_context(|| format!("opening the cache database {cache_db}"))?;
    let store = OsmTileStore::new(pool.clone());
    let mut report = import_files(files, &store, quiet).await?;
    report.tiles_invalidated = drop_stored(&TileStore::new(pool), &report.changed_areas).await?;
    Ok(report)
}

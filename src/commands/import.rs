//! `citymesh import FILE...`: OSM files into the data-tile store (`crate::source::data_tiles`),
//! then the stored tiles generated from data that changed are dropped (`crate::cache`). On
//! SQLite, run it while the server is stopped, or restart the server after it: a running server
//! keeps the data it already parsed in memory. On PostgreSQL, running replicas are told which
//! areas changed (in the transaction that drops their tiles) and drop what they hold of them.

use crate::cache::TileStore;
use crate::cache::invalidation::drop_stored;
use crate::db::{self, Database};
use crate::source::data_tiles::OsmTileStore;
use crate::source::data_tiles::import::{ImportOptions, ImportReport, import_files};
use anyhow::Context;
use std::path::PathBuf;

/// Imports the files into the SQLite database at `cache_db`. `quiet` hides the progress bars.
pub async fn import(
    files: &[PathBuf],
    cache_db: &str,
    quiet: bool,
) -> anyhow::Result<ImportReport> {
    let pool = db::open(cache_db)
        .await
        .with_context(|| format!("opening the cache database {cache_db}"))?;
    import_into(files, &Database::Sqlite(pool), quiet).await
}

/// Imports the files into `db` with the default memory budget. `quiet` hides the progress bars.
pub async fn import_into(
    files: &[PathBuf],
    db: &Database,
    quiet: bool,
) -> anyhow::Result<ImportReport> {
    let options = ImportOptions {
        quiet,
        ..ImportOptions::default()
    };
    import_with(files, db, &options).await
}

/// Imports the files into `db` as `options` say.
pub async fn import_with(
    files: &[PathBuf],
    db: &Database,
    options: &ImportOptions,
) -> anyhow::Result<ImportReport> {
    let store = OsmTileStore::new(db.clone());
    let mut report = import_files(files, &store, options).await?;
    let tiles = TileStore::open(db, u64::MAX, "import").await?;
    report.tiles_invalidated = drop_stored(&tiles, &report.changed_areas).await?;
    Ok(report)
}

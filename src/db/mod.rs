//! The SQLite database: opened through sqlx with the migrations of `migrations/` applied at
//! start-up. Each table has its own small store type beside its user: generated tiles in
//! `crate::cache` (`cache/store.rs`), OSM data tiles in `crate::source::data_tiles`.

use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use std::str::FromStr;

/// Opens (creating if needed) the database at `location` (a file path, or `:memory:`) and applies
/// the migrations.
pub async fn open(location: &str) -> anyhow::Result<SqlitePool> {
    let memory = location == ":memory:";
    let options = if memory {
        SqliteConnectOptions::from_str("sqlite::memory:")?
    } else {
        let path = std::path::Path::new(location);
        if let Some(parent) = path.parent()
            && !parent.as_os_str().is_empty()
        {
            if let Some(file) = parent.ancestors().find(|a| a.is_file()) {
                anyhow::bail!(
                    "{} is a file, so the cache database {location} cannot be created under it: \
                     pass --cache-db a path in a folder",
                    file.display()
                );
            }
            std::fs::create_dir_all(parent).map_err(|e| {
                anyhow::anyhow!(
                    "cannot create the folder {} for the cache database ({e}): check it is \
                     writable by this user, or pass --cache-db another path",
                    parent.display()
                )
            })?;
        }
        if path.is_dir() {
            anyhow::bail!(
                "{location} is a folder: pass --cache-db a file path, e.g. {location}/citymesh.sqlite"
            );
        }
        SqliteConnectOptions::new()
            .filename(location)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            // With WAL, NORMAL syncs at checkpoints, not at every commit: a commit survives the
            // process crashing (it is in the WAL file); only a power cut can lose the last few.
            // The database is a cache and a job queue whose jobs are retried, so that is fine.
            .synchronous(SqliteSynchronous::Normal)
    };
    // An in-memory database exists once per connection: keep exactly one.
    let pool = SqlitePoolOptions::new()
        .max_connections(if memory { 1 } else { 4 })
        .min_connections(if memory { 1 } else { 0 })
        .idle_timeout(None)
        .max_lifetime(None)
        .connect_with(options)
        .await
        .map_err(|e| {
            anyhow::anyhow!(
                "cannot open the cache database {location} ({e}): check that this user may read \
                 and write it and its folder (permissions), or pass --cache-db another path"
            )
        })?;
    sqlx::migrate!("./migrations").run(&pool).await?;
    Ok(pool)
}

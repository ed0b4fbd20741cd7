//! The SQLite database: opened through sqlx with the migrations of `migrations/` applied at
//! start-up. Each table has its own small store type beside its user: generated tiles in
//! `crate::cache` (`cache/store.rs`), OSM data tiles in `crate::source::data_tiles`.

use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions};
use std::str::FromStr;

/// Opens (creating if needed) the database at `location` (a file path, or `:memory:`) and applies
/// the migrations.
pub async fn open(location: &str) -> anyhow::Result<SqlitePool> {
    let memory = location == ":memory:";
    let options = if memory {
        SqliteConnectOptions::from_str("sqlite::memory:")?
    } else {
        if let Some(parent) = std::path::Path::new(location).parent()
            && !parent.as_os_str().is_empty()
        {
            std::fs::create_dir_all(parent)?;
        }
        SqliteConnectOptions::new()
            .filename(location)
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
    };
    // An in-memory database exists once per connection: keep exactly one.
    let pool = SqlitePoolOptions::new()
        .max_connections(if memory { 1 } else { 4 })
        .min_connections(if memory { 1 } else { 0 })
        .idle_timeout(None)
        .max_lifetime(None)
        .connect_with(options)
        .await?;
    sqlx::migrate!("./migrations").run(&pool).await?;
    Ok(pool)
}

//! The SQLite database (the single-machine default, `--cache-db`): opened through sqlx with the
//! migrations of `migrations/` applied at start-up.

use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use std::str::FromStr;

use super::BUSY_TIMEOUT;

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
            // A writer waits this long for another's transaction to end, then the request gets a
            // 503 (see `is_busy`). Writes are short (jobs are queued in chunks), so waiting is
            // rare; readers never wait (WAL, and reads do not write).
            .busy_timeout(BUSY_TIMEOUT)
    };
    // An in-memory database exists once per connection: keep exactly one.
    let pool = SqlitePoolOptions::new()
        .max_connections(if memory { 1 } else { 8 })
        .acquire_timeout(BUSY_TIMEOUT)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::is_busy;
    use sqlx::Connection;

    #[tokio::test]
    async fn a_write_that_waits_too_long_for_the_lock_is_busy_not_a_failure() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.sqlite");
        let pool = open(path.to_str().unwrap()).await.unwrap();
        // Another process holds the write lock.
        let mut other = sqlx::SqliteConnection::connect_with(
            &SqliteConnectOptions::new()
                .filename(&path)
                .busy_timeout(std::time::Duration::ZERO),
        )
        .await
        .unwrap();
        sqlx::query("BEGIN IMMEDIATE")
            .execute(&mut other)
            .await
            .unwrap();
        let mut impatient = sqlx::SqliteConnection::connect_with(
            &SqliteConnectOptions::new()
                .filename(&path)
                .busy_timeout(std::time::Duration::from_millis(10)),
        )
        .await
        .unwrap();
        let e = sqlx::query("BEGIN IMMEDIATE")
            .execute(&mut impatient)
            .await
            .unwrap_err();
        assert!(is_busy(&e), "{e:?}");
        assert!(!is_busy(&sqlx::Error::RowNotFound));
        // A client is told to come back, never given a 500.
        use axum::response::IntoResponse;
        let answer = crate::error::AppError::from(e).into_response();
        assert_eq!(answer.status(), axum::http::StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(answer.headers()["retry-after"], "2");
        // Reads go on meanwhile.
        let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM generated_tiles")
            .fetch_one(&pool)
            .await
            .unwrap();
        assert_eq!(n, 0);
    }
}

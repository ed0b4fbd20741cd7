//! The database every store lives in: SQLite on one machine (the default, `--cache-db`), or a
//! PostgreSQL server shared by many replicas (`--database-url postgres://...`). Each store lives
//! beside its user and is opened on a [`Database`]: its statements written once and run on
//! either pool by `on_pool!`, writes begun by [`BeginWrite`] (`cache/store/`,
//! `source/data_tiles/store/`, `roofs/imagery/cache.rs`, `roofs/jobs/queue/`).

mod postgres;
mod sqlite;
mod use_notes;

pub use postgres::open_postgres;
pub use sqlite::open;
pub use use_notes::UseNotes;

use sqlx::{PgPool, SqlitePool};

/// Runs `$body` with `$pool` bound to the pool of whichever backend `$db` is, for statements
/// that read the same on both (`$n` placeholders, which SQLite takes too).
macro_rules! on_pool {
    ($db:expr, $pool:ident => $body:expr) => {
        match $db {
            $crate::db::Database::Sqlite($pool) => $body,
            $crate::db::Database::Postgres($pool) => $body,
        }
    };
}
pub(crate) use on_pool;

/// A pool whose write transactions start as its backend wants them to.
pub(crate) trait BeginWrite {
    type Backend: sqlx::Database;

    /// Begins a write: SQLite takes the write lock at once (`BEGIN IMMEDIATE`: two writers
    /// never deadlock upgrading a read lock, and a busy database answers now); PostgreSQL
    /// begins as usual (row locks are taken by the statements).
    fn begin_write(
        &self,
    ) -> impl std::future::Future<
        Output = Result<sqlx::Transaction<'static, Self::Backend>, sqlx::Error>,
    > + Send;
}

impl BeginWrite for SqlitePool {
    type Backend = sqlx::Sqlite;

    async fn begin_write(&self) -> Result<sqlx::Transaction<'static, sqlx::Sqlite>, sqlx::Error> {
        self.begin_with("BEGIN IMMEDIATE").await
    }
}

impl BeginWrite for PgPool {
    type Backend = sqlx::Postgres;

    async fn begin_write(&self) -> Result<sqlx::Transaction<'static, sqlx::Postgres>, sqlx::Error> {
        self.begin().await
    }
}

/// How long a statement waits for a lock, and a request for a connection.
const BUSY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);

/// The opened database.
#[derive(Clone, Debug)]
pub enum Database {
    Sqlite(SqlitePool),
    Postgres(PgPool),
}

impl Database {
    /// PostgreSQL at `database_url` when given (with at most `max_connections`), else the SQLite
    /// file `cache_db`; migrations applied either way.
    pub async fn open(
        database_url: Option<&str>,
        cache_db: &str,
        max_connections: u32,
    ) -> anyhow::Result<Self> {
        Ok(match database_url {
            Some(url) => Self::Postgres(open_postgres(url, max_connections).await?),
            None => Self::Sqlite(open(cache_db).await?),
        })
    }

    /// `sqlite` or `postgres`.
    pub fn backend(&self) -> &'static str {
        match self {
            Self::Sqlite(_) => "sqlite",
            Self::Postgres(_) => "postgres",
        }
    }

    /// Whether the database answers a trivial query now.
    pub async fn ping(&self) -> Result<(), sqlx::Error> {
        match self {
            Self::Sqlite(p) => sqlx::query("SELECT 1").execute(p).await.map(drop),
            Self::Postgres(p) => sqlx::query("SELECT 1").execute(p).await.map(drop),
        }
    }
}

/// Whether the database was too busy to answer in time (locked by writers, every connection
/// taken, or too many clients): worth trying again, never a 500.
pub fn is_busy(e: &sqlx::Error) -> bool {
    match e {
        sqlx::Error::PoolTimedOut => true,
        sqlx::Error::Database(d) => {
            if d.try_downcast_ref::<sqlx::postgres::PgDatabaseError>()
                .is_some()
            {
                // too_many_connections, lock_not_available, serialization_failure,
                // deadlock_detected.
                return d
                    .code()
                    .is_some_and(|c| matches!(&*c, "53300" | "55P03" | "40001" | "40P01"));
            }
            d.code().is_some_and(|code| {
                // SQLITE_BUSY (5) and SQLITE_LOCKED (6), with their extended codes.
                code.parse::<i32>().is_ok_and(|c| matches!(c & 0xff, 5 | 6))
            })
        }
        _ => false,
    }
}

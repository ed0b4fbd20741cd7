//! The stored level of the tile cache: generated content under typed keys, bounded in bytes, on
//! the database the server was given: SQLite on one machine ([`SqliteTileStore`]), PostgreSQL
//! shared by replicas ([`PgTileStore`]). [`TileStore`] is whichever was opened; its methods are
//! the contract both keep.

mod postgres;
mod sqlite;

pub use postgres::{DATA_CHANGED_CHANNEL, DataChangedNote, PgGenerationLock, PgTileStore};
pub use sqlite::SqliteTileStore;

use super::key::{TileId, TileKey};
use crate::db::Database;
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use std::time::Duration;

/// A stored tile: its bytes and their ETag.
#[derive(Debug, Clone)]
pub struct StoredTile {
    pub bytes: Bytes,
    pub etag: String,
}

#[derive(Clone)]
pub enum TileStore {
    Sqlite(SqliteTileStore),
    Postgres(PgTileStore),
}

/// A held right to generate a tile other processes may also miss: writing the tile with it
/// releases them.
pub enum GenerationLock {
    Postgres(PgGenerationLock),
}

/// What a miss should do, decided across processes sharing the store.
pub enum GenerationTurn {
    /// Generate the tile (holding `lock` when the store coordinates processes).
    Generate {
        lock: Option<GenerationLock>,
        /// Another process held the key's lock first.
        waited: bool,
        /// ... and did not finish within the wait.
        timed_out: bool,
    },
    /// Another process generated it meanwhile.
    Stored { tile: StoredTile, waited: bool },
}

impl TileStore {
    /// The store with writes and uses stamped by `clock` (tests move a manual one).
    pub fn with_clock(self, clock: crate::clock::Clock) -> Self {
        match self {
            Self::Sqlite(s) => Self::Sqlite(s.with_clock(clock)),
            Self::Postgres(s) => Self::Postgres(s.with_clock(clock)),
        }
    }

    /// The store on `db`, bounded to `max_bytes`, announcing data changes as `replica`.
    pub async fn open(db: &Database, max_bytes: u64, replica: &str) -> Result<Self, sqlx::Error> {
        Ok(match db {
            Database::Sqlite(pool) => {
                Self::Sqlite(SqliteTileStore::bounded(pool.clone(), max_bytes).await?)
            }
            Database::Postgres(pool) => {
                Self::Postgres(PgTileStore::bounded(pool.clone(), max_bytes, replica).await?)
            }
        })
    }

    /// Bytes of stored tiles.
    pub fn used_bytes(&self) -> u64 {
        match self {
            Self::Sqlite(s) => s.used_bytes(),
            Self::Postgres(s) => s.used_bytes(),
        }
    }

    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        match self {
            Self::Sqlite(s) => s.get(key, data_version).await,
            Self::Postgres(s) => s.get(key, data_version).await,
        }
    }

    /// Whose turn it is to generate a tile this process missed: on SQLite always this
    /// process's (one process owns the file); on PostgreSQL see [`PgTileStore::turn`].
    pub async fn turn(
        &self,
        key: &TileKey,
        data_version: &str,
        wait: Duration,
    ) -> Result<GenerationTurn, sqlx::Error> {
        match self {
            Self::Sqlite(_) => Ok(GenerationTurn::Generate {
                lock: None,
                waited: false,
                timed_out: false,
            }),
            Self::Postgres(s) => s.turn(key, data_version, wait).await,
        }
    }

    /// Stores a tile, replacing the key's row (and releasing `lock`), then evicts the least
    /// recently used tiles past the bound.
    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
        lock: Option<GenerationLock>,
    ) -> Result<(), sqlx::Error> {
        match self {
            Self::Sqlite(s) => s.put(key, data_version, bytes, etag).await,
            Self::Postgres(s) => {
                let lock = lock.map(|GenerationLock::Postgres(l)| l);
                s.put(key, data_version, bytes, etag, lock).await
            }
        }
    }

    /// Deletes one key's row, if stored.
    pub async fn remove(&self, key: &TileKey, data_version: &str) -> Result<(), sqlx::Error> {
        match self {
            Self::Sqlite(s) => s.remove(key, data_version).await,
            Self::Postgres(s) => s.remove(key, data_version).await,
        }
    }

    /// Deletes every stored tile (any scheme, encoding or version) whose ground overlaps `area`
    /// (on PostgreSQL, telling every replica); answers how many.
    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        match self {
            Self::Sqlite(s) => s.delete_overlapping(area).await,
            Self::Postgres(s) => s.delete_overlapping(area).await,
        }
    }
}

/// The key's columns: scheme, region text, z, x, y.
fn columns(key: &TileKey) -> (&'static str, String, i64, i64, i64) {
    let scheme = key.tile.scheme();
    match key.tile {
        TileId::Xyz(t) => (
            scheme,
            String::new(),
            i64::from(t.z),
            i64::from(t.x),
            i64::from(t.y),
        ),
        TileId::Implicit { root, tile } => (
            scheme,
            root.0.to_string(),
            i64::from(tile.level),
            i64::from(tile.x),
            i64::from(tile.y),
        ),
        TileId::Bbox(b) => (scheme, b.0.to_string(), 0, 0, 0),
    }
}

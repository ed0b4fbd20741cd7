//! Fetched imagery tiles in the database (SQLite, or PostgreSQL shared by replicas), with a
//! time to live and a size bound. Each statement is written once for both backends
//! (`crate::db::on_pool!`), but eviction, which names rows as each backend does.
//! Tested on both in `tests/it/storage_backends.rs`.

use crate::clock::Clock;
use crate::db::{Database, on_pool};
use citymesh_core::geo::TileCoord;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

pub struct ImageryCache {
    db: Database,
    ttl: Duration,
    max_bytes: u64,
    /// Bytes stored, as last counted (counted at start and after each eviction, grown by puts).
    stored: AtomicI64,
    /// What fetches and uses are stamped with, and the time to live counted by.
    clock: Clock,
}

impl ImageryCache {
    pub async fn new(db: Database, ttl: Duration, max_bytes: u64) -> sqlx::Result<Self> {
        let stored = stored_bytes(&db).await?;
        Ok(Self {
            db,
            ttl,
            max_bytes,
            stored: AtomicI64::new(stored),
            clock: Clock::system(),
        })
    }

    /// The cache with its rows stamped by `clock` (tests move a manual one).
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// The stored bytes of a tile younger than the time to live.
    pub async fn get(&self, imagery_id: &str, t: TileCoord) -> sqlx::Result<Option<Vec<u8>>> {
        let now = self.clock.now_ms();
        let oldest = now.saturating_sub(i64::try_from(self.ttl.as_millis()).unwrap_or(i64::MAX));
        let sql = "UPDATE imagery_tiles SET last_used = $1 WHERE imagery_id = $2 AND z = $3 \
                   AND x = $4 AND y = $5 AND fetched_at >= $6 RETURNING bytes";
        on_pool!(&self.db, pool => sqlx::query_scalar(sql)
            .bind(now)
            .bind(imagery_id)
            .bind(i64::from(t.z))
            .bind(i64::from(t.x))
            .bind(i64::from(t.y))
            .bind(oldest)
            .fetch_optional(pool)
            .await)
    }

    /// Stores a tile, then evicts the least recently used while the table is over its bound.
    pub async fn put(&self, imagery_id: &str, t: TileCoord, bytes: &[u8]) -> sqlx::Result<()> {
        if bytes.len() as u64 > self.max_bytes {
            return Ok(());
        }
        let now = self.clock.now_ms();
        let sql = "INSERT INTO imagery_tiles (imagery_id, z, x, y, bytes, fetched_at, last_used) \
                   VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (imagery_id, z, x, y) DO \
                   UPDATE SET bytes = excluded.bytes, fetched_at = excluded.fetched_at, \
                   last_used = excluded.last_used";
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(imagery_id)
            .bind(i64::from(t.z))
            .bind(i64::from(t.x))
            .bind(i64::from(t.y))
            .bind(bytes)
            .bind(now)
            .bind(now)
            .execute(pool)
            .await
            .map(drop))?;
        let stored = self.stored.fetch_add(
            i64::try_from(bytes.len()).unwrap_or(i64::MAX),
            Ordering::Relaxed,
        );
        if stored as u64 + bytes.len() as u64 > self.max_bytes {
            self.evict().await?;
        }
        Ok(())
    }

    /// Deletes the least recently used tiles until the table holds at most 90 % of the bound.
    /// The one statement that differs: how a row is named (`rowid` or `ctid`).
    async fn evict(&self) -> sqlx::Result<()> {
        let target = i64::try_from(self.max_bytes / 10 * 9).unwrap_or(i64::MAX);
        let sql = match &self.db {
            Database::Sqlite(_) => {
                "DELETE FROM imagery_tiles WHERE rowid IN (SELECT rowid FROM (SELECT rowid, \
                 SUM(length(bytes)) OVER (ORDER BY last_used DESC, rowid DESC) AS kept \
                 FROM imagery_tiles) WHERE kept > $1)"
            }
            Database::Postgres(_) => {
                "DELETE FROM imagery_tiles WHERE ctid IN (SELECT ctid FROM (SELECT ctid, \
                 SUM(length(bytes)) OVER (ORDER BY last_used DESC, imagery_id DESC, z DESC, \
                 x DESC, y DESC) AS kept FROM imagery_tiles) t WHERE kept > $1)"
            }
        };
        on_pool!(&self.db, pool => sqlx::query(sql)
            .bind(target)
            .execute(pool)
            .await
            .map(drop))?;
        self.stored
            .store(stored_bytes(&self.db).await?, Ordering::Relaxed);
        Ok(())
    }
}

/// Bytes of stored imagery, counted.
async fn stored_bytes(db: &Database) -> sqlx::Result<i64> {
    let sql = "SELECT CAST(COALESCE(SUM(length(bytes)), 0) AS BIGINT) FROM imagery_tiles";
    on_pool!(db, pool => sqlx::query_scalar(sql).fetch_one(pool).await)
}

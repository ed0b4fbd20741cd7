//! OSM data tiles kept in SQLite with their fetch time, so the server can run offline and a
//! restart does not ask upstream again. What came from Overpass is bounded in bytes
//! (`--osm-store-mb`): past the bound the least recently used data tiles are deleted (and
//! fetched again when needed); imported data is never evicted. Reads note their use in memory
//! and never write.

use crate::db::UseNotes;
use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use sqlx::{Row, SqlitePool};
use std::sync::Arc;

/// Where a stored data tile came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataOrigin {
    Overpass,
    Import,
}

impl DataOrigin {
    fn as_str(self) -> &'static str {
        match self {
            DataOrigin::Overpass => "overpass",
            DataOrigin::Import => "import",
        }
    }
}

/// One stored data tile.
#[derive(Debug, Clone)]
pub struct StoredDataTile {
    pub body: Bytes,
    pub hash: String,
    pub origin: DataOrigin,
    /// Unix seconds.
    pub fetched_at: i64,
}

#[derive(Clone)]
pub struct OsmTileStore {
    pool: SqlitePool,
    /// Bytes of Overpass data at most (`u64::MAX`: unbounded).
    max_bytes: u64,
    /// Data tiles read since their uses were last written.
    uses: Arc<UseNotes<TileCoord>>,
    /// One eviction at a time.
    evicting: Arc<tokio::sync::Mutex<()>>,
}

/// Uses noted before they are written with the next stored tile.
const MAX_NOTED_USES: usize = 4_096;

fn now_ms() -> i64 {
    now_secs().saturating_mul(1000)
}

/// The content hash stored with a body.
pub fn content_hash(body: &[u8]) -> String {
    format!("{:016x}", xxhash_rust::xxh3::xxh3_64(body))
}

pub fn now_secs() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

impl OsmTileStore {
    /// An unbounded store (for `citymesh import` and tests).
    pub fn new(pool: SqlitePool) -> Self {
        Self::bounded(pool, u64::MAX)
    }

    /// A store whose Overpass data is kept under `max_bytes`.
    pub fn bounded(pool: SqlitePool, max_bytes: u64) -> Self {
        Self {
            pool,
            max_bytes,
            uses: Arc::new(UseNotes::new(MAX_NOTED_USES)),
            evicting: Arc::new(tokio::sync::Mutex::new(())),
        }
    }

    /// Bytes of stored Overpass data.
    pub async fn overpass_bytes(&self) -> Result<u64, sqlx::Error> {
        let used: i64 = sqlx::query(
            "SELECT COALESCE(SUM(size), 0) FROM osm_data_tiles WHERE source = 'overpass'",
        )
        .fetch_one(&self.pool)
        .await?
        .get(0);
        Ok(u64::try_from(used).unwrap_or(0))
    }

    /// Writes the noted uses, then deletes the least recently used Overpass data tiles, one at a
    /// time (each holds many buildings), while there are more bytes than the bound.
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        if self.max_bytes == u64::MAX {
            return Ok(());
        }
        let _one = self.evicting.lock().await;
        let uses = self.uses.take();
        if !uses.is_empty() {
            let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
            for (t, at) in &uses {
                sqlx::query(
                    "UPDATE osm_data_tiles SET last_used = MAX(last_used, ?) \
                     WHERE z = ? AND x = ? AND y = ?",
                )
                .bind(*at)
                .bind(i64::from(t.z))
                .bind(i64::from(t.x))
                .bind(i64::from(t.y))
                .execute(&mut *tx)
                .await?;
            }
            tx.commit().await?;
        }
        let mut used = self.overpass_bytes().await?;
        while used > self.max_bytes {
            let sizes: Vec<i64> = sqlx::query(
                "DELETE FROM osm_data_tiles WHERE rowid IN (SELECT rowid FROM osm_data_tiles \
                 WHERE source = 'overpass' ORDER BY last_used, rowid LIMIT 1) RETURNING size",
            )
            .fetch_all(&self.pool)
            .await?
            .iter()
            .map(|r| r.get(0))
            .collect();
            if sizes.is_empty() {
                break;
            }
            let freed: i64 = sizes.iter().sum();
            used = used.saturating_sub(u64::try_from(freed).unwrap_or(0));
            tracing::debug!(
                evicted = sizes.len(),
                used,
                "OSM data store evicted data tiles"
            );
        }
        Ok(())
    }

    pub async fn get(&self, t: &TileCoord) -> Result<Option<StoredDataTile>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT body, hash, source, fetched_at FROM osm_data_tiles WHERE z = ? AND x = ? AND y = ?",
        )
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .fetch_optional(&self.pool)
        .await?;
        if row.is_some() {
            // Written with the next stored tile; when many are noted, it is time.
            self.uses.note(*t, now_ms());
        }
        Ok(row.map(|r| StoredDataTile {
            body: Bytes::from(r.get::<Vec<u8>, _>(0)),
            hash: r.get(1),
            origin: if r.get::<String, _>(2) == "import" {
                DataOrigin::Import
            } else {
                DataOrigin::Overpass
            },
            fetched_at: r.get(3),
        }))
    }

    /// Stores a data tile; answers whether its content changed (new, or a different body).
    pub async fn put(
        &self,
        t: &TileCoord,
        body: &[u8],
        origin: DataOrigin,
    ) -> Result<bool, sqlx::Error> {
        let hash = content_hash(body);
        let previous: Option<String> =
            sqlx::query("SELECT hash FROM osm_data_tiles WHERE z = ? AND x = ? AND y = ?")
                .bind(i64::from(t.z))
                .bind(i64::from(t.x))
                .bind(i64::from(t.y))
                .fetch_optional(&self.pool)
                .await?
                .map(|r| r.get(0));
        sqlx::query(
            "INSERT OR REPLACE INTO osm_data_tiles (z, x, y, body, hash, source, fetched_at, \
             size, last_used) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .bind(body)
        .bind(&hash)
        .bind(origin.as_str())
        .bind(now_secs())
        .bind(i64::try_from(body.len()).unwrap_or(i64::MAX))
        .bind(now_ms())
        .execute(&self.pool)
        .await?;
        if origin == DataOrigin::Overpass {
            self.evict_if_over().await?;
        }
        Ok(previous.as_deref() != Some(hash.as_str()))
    }

    /// Number of stored data tiles.
    pub async fn count(&self) -> Result<i64, sqlx::Error> {
        sqlx::query("SELECT COUNT(*) FROM osm_data_tiles")
            .fetch_one(&self.pool)
            .await
            .map(|r| r.get(0))
    }
}

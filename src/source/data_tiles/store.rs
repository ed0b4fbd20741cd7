//! OSM data tiles kept in SQLite with their fetch time, so the server can run offline and a
//! restart does not ask upstream again.

use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use sqlx::{Row, SqlitePool};

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
    pub fn new(pool: SqlitePool) -> Self {
        Self { pool }
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
            "INSERT OR REPLACE INTO osm_data_tiles (z, x, y, body, hash, source, fetched_at) VALUES (?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .bind(body)
        .bind(&hash)
        .bind(origin.as_str())
        .bind(now_secs())
        .execute(&self.pool)
        .await?;
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

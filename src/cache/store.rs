//! The SQLite level of the tile cache: generated content under typed keys, so it survives a
//! restart.

use super::key::{TileId, TileKey};
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use sqlx::{Row, SqlitePool};

/// A stored tile: its bytes and their ETag.
#[derive(Debug, Clone)]
pub struct StoredTile {
    pub bytes: Bytes,
    pub etag: String,
}

#[derive(Clone)]
pub struct TileStore {
    pool: SqlitePool,
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

impl TileStore {
    pub fn new(pool: SqlitePool) -> Self {
        Self { pool }
    }

    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        let (scheme, region, z, x, y) = columns(key);
        let row = sqlx::query(
            "SELECT bytes, etag FROM generated_tiles WHERE scheme = ? AND region = ? AND z = ? \
             AND x = ? AND y = ? AND encoding = ? AND roofs = ? AND data_version = ?",
        )
        .bind(scheme)
        .bind(region)
        .bind(z)
        .bind(x)
        .bind(y)
        .bind(key.encoding.as_str())
        .bind(key.roofs.as_str())
        .bind(data_version)
        .fetch_optional(&self.pool)
        .await?;
        Ok(row.map(|r| StoredTile {
            bytes: Bytes::from(r.get::<Vec<u8>, _>(0)),
            etag: r.get(1),
        }))
    }

    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
    ) -> Result<(), sqlx::Error> {
        let (scheme, region, z, x, y) = columns(key);
        let b = key.tile.bounds();
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        sqlx::query(
            "INSERT OR REPLACE INTO generated_tiles (scheme, region, z, x, y, encoding, roofs, \
             data_version, west, south, east, north, bytes, etag, created_at) \
             VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        )
        .bind(scheme)
        .bind(region)
        .bind(z)
        .bind(x)
        .bind(y)
        .bind(key.encoding.as_str())
        .bind(key.roofs.as_str())
        .bind(data_version)
        .bind(b.min_lon())
        .bind(b.min_lat())
        .bind(b.max_lon())
        .bind(b.max_lat())
        .bind(bytes)
        .bind(etag)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Deletes every stored tile (any scheme, encoding or version) whose ground overlaps `area`.
    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        Ok(sqlx::query(
            "DELETE FROM generated_tiles WHERE west <= ? AND east >= ? AND south <= ? AND north >= ?",
        )
        .bind(area.max_lon())
        .bind(area.min_lon())
        .bind(area.max_lat())
        .bind(area.min_lat())
        .execute(&self.pool)
        .await?
        .rows_affected())
    }

    /// Number of stored tiles.
    pub async fn count(&self) -> Result<i64, sqlx::Error> {
        sqlx::query("SELECT COUNT(*) FROM generated_tiles")
            .fetch_one(&self.pool)
            .await
            .map(|r| r.get(0))
    }
}

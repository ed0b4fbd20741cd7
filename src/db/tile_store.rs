//! Generated tiles kept in SQLite, so they survive a restart.

use bytes::Bytes;
use sqlx::{Row, SqlitePool};

/// Identifies one stored tile: its coordinate and everything else its bytes depend on.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TileKey {
    pub z: u8,
    pub x: u32,
    pub y: u32,
    pub variant: String,
}

#[derive(Clone)]
pub struct TileStore {
    pool: SqlitePool,
}

impl TileStore {
    pub fn new(pool: SqlitePool) -> Self {
        Self { pool }
    }

    pub async fn get(&self, key: &TileKey) -> Result<Option<Bytes>, sqlx::Error> {
        let row = sqlx::query(
            "SELECT glb FROM generated_tiles WHERE z = ? AND x = ? AND y = ? AND variant = ?",
        )
        .bind(i64::from(key.z))
        .bind(i64::from(key.x))
        .bind(i64::from(key.y))
        .bind(&key.variant)
        .fetch_optional(&self.pool)
        .await?;
        Ok(row.map(|r| Bytes::from(r.get::<Vec<u8>, _>(0))))
    }

    pub async fn put(&self, key: &TileKey, glb: &[u8]) -> Result<(), sqlx::Error> {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs() as i64)
            .unwrap_or(0);
        sqlx::query(
            "INSERT OR REPLACE INTO generated_tiles (z, x, y, variant, glb, created_at) VALUES (?, ?, ?, ?, ?, ?)",
        )
        .bind(i64::from(key.z))
        .bind(i64::from(key.x))
        .bind(i64::from(key.y))
        .bind(&key.variant)
        .bind(glb)
        .bind(now)
        .execute(&self.pool)
        .await?;
        Ok(())
    }

    /// Deletes the tiles in each `(z, x0, x1, y0, y1)` range (inclusive), of any variant.
    pub async fn delete_ranges(
        &self,
        ranges: &[(u8, u32, u32, u32, u32)],
    ) -> Result<u64, sqlx::Error> {
        let mut removed = 0;
        for &(z, x0, x1, y0, y1) in ranges {
            removed += sqlx::query(
                "DELETE FROM generated_tiles WHERE z = ? AND x BETWEEN ? AND ? AND y BETWEEN ? AND ?",
            )
            .bind(i64::from(z))
            .bind(i64::from(x0))
            .bind(i64::from(x1))
            .bind(i64::from(y0))
            .bind(i64::from(y1))
            .execute(&self.pool)
            .await?
            .rows_affected();
        }
        Ok(removed)
    }

    /// Deletes the tiles whose variant contains `mark`.
    pub async fn delete_variants_containing(&self, mark: &str) -> Result<u64, sqlx::Error> {
        Ok(
            sqlx::query("DELETE FROM generated_tiles WHERE instr(variant, ?) > 0")
                .bind(mark)
                .execute(&self.pool)
                .await?
                .rows_affected(),
        )
    }

    /// Number of stored tiles.
    pub async fn count(&self) -> Result<i64, sqlx::Error> {
        sqlx::query("SELECT COUNT(*) FROM generated_tiles")
            .fetch_one(&self.pool)
            .await
            .map(|r| r.get(0))
    }
}

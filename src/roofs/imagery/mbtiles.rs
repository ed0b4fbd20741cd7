//! Imagery from a local MBTiles file (an SQLite database of PNG or JPEG tiles, rows counted from
//! the south as in TMS), opened read-only.

use super::ImageryError;
use citymesh_core::geo::TileCoord;
use sqlx::SqlitePool;
use sqlx::sqlite::{SqliteConnectOptions, SqlitePoolOptions};

pub struct MbTiles {
    pool: SqlitePool,
}

impl MbTiles {
    /// Opens `path` read-only; answers it and the deepest zoom it holds.
    pub async fn open(path: &std::path::Path) -> anyhow::Result<(Self, Option<u8>)> {
        anyhow::ensure!(
            path.is_file(),
            "the MBTiles file {} does not exist",
            path.display()
        );
        let options = SqliteConnectOptions::new()
            .filename(path)
            .read_only(true)
            .immutable(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(2)
            .connect_with(options)
            .await
            .map_err(|e| anyhow::anyhow!("{} is not an MBTiles file: {e}", path.display()))?;
        let max: Option<i64> = sqlx::query_scalar("SELECT MAX(zoom_level) FROM tiles")
            .fetch_one(&pool)
            .await
            .map_err(|e| anyhow::anyhow!("{} has no readable tiles table: {e}", path.display()))?;
        Ok((Self { pool }, max.and_then(|z| u8::try_from(z).ok())))
    }

    /// The tile's bytes; `NotFound` when the file has none there.
    pub async fn bytes(&self, t: TileCoord) -> Result<Vec<u8>, ImageryError> {
        let tms_row = (1i64 << t.z) - 1 - i64::from(t.y);
        sqlx::query_scalar(
            "SELECT tile_data FROM tiles WHERE zoom_level = ? AND tile_column = ? AND tile_row = ?",
        )
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(tms_row)
        .fetch_optional(&self.pool)
        .await
        .map_err(|e| ImageryError::Bad(format!("MBTiles: {e}")))?
        .ok_or(ImageryError::NotFound)
    }
}

//! The generated tiles on PostgreSQL (work in progress, issue 27): the same rows and bound as
//! [`super::store::TileStore`] on SQLite, shared by every replica.

use super::key::{TileId, TileKey};
use super::store::StoredTile;
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use sqlx::{PgPool, Row};

/// What a row costs beyond its bytes, estimated (TOAST pages and the row header).
const ROW_OVERHEAD: i64 = 2_560;

#[derive(Clone)]
pub struct PgTileStore {
    pool: PgPool,
    max_bytes: u64,
}

fn columns(key: &TileKey) -> (&'static str, String, i64, i64, i64) {
    let scheme = key.tile.scheme();
    match key.tile {
        TileId::Xyz(t) => (scheme, String::new(), t.z.into(), t.x.into(), t.y.into()),
        TileId::Implicit { root, tile } => (
            scheme,
            root.0.to_string(),
            tile.level.into(),
            tile.x.into(),
            tile.y.into(),
        ),
        TileId::Bbox(b) => (scheme, b.0.to_string(), 0, 0, 0),
    }
}

/// The condition that selects one key's row; [`bind_key`] binds $1 to $8.
macro_rules! key_where {
    () => {
        "scheme = $1 AND region = $2 AND z = $3 AND x = $4 AND y = $5 AND encoding = $6 \
         AND roofs = $7 AND data_version = $8"
    };
}

type Query<'q> = sqlx::query::Query<'q, sqlx::Postgres, sqlx::postgres::PgArguments>;

fn bind_key<'q>(query: Query<'q>, key: &TileKey, data_version: &str) -> Query<'q> {
    let (scheme, region, z, x, y) = columns(key);
    query
        .bind(scheme)
        .bind(region)
        .bind(z)
        .bind(x)
        .bind(y)
        .bind(key.encoding.as_str())
        .bind(key.roofs.name())
        .bind(data_version.to_owned())
}

fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

impl PgTileStore {
    pub fn new(pool: PgPool, max_bytes: u64) -> Self {
        Self { pool, max_bytes }
    }

    /// Bytes of stored tiles (counted by the database, so every replica sees the same).
    pub async fn used_bytes(&self) -> Result<u64, sqlx::Error> {
        let used: i64 = sqlx::query("SELECT COALESCE(SUM(size), 0)::BIGINT FROM generated_tiles")
            .fetch_one(&self.pool)
            .await?
            .get(0);
        Ok(u64::try_from(used).unwrap_or(0))
    }

    /// The stored tile; its use is written at once.
    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        let sql = concat!(
            "UPDATE generated_tiles SET last_used = GREATEST(last_used, $9) WHERE ",
            key_where!(),
            " RETURNING bytes, etag"
        );
        let row = bind_key(sqlx::query(sql), key, data_version)
            .bind(now_ms())
            .fetch_optional(&self.pool)
            .await?;
        Ok(row.map(|row| StoredTile {
            bytes: Bytes::from(row.get::<Vec<u8>, _>(0)),
            etag: row.get(1),
        }))
    }

    /// Stores a tile (replacing the key's row), then evicts the least recently used past the
    /// bound.
    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
    ) -> Result<(), sqlx::Error> {
        let b = key.tile.bounds();
        let now = now_ms();
        let sql = "INSERT INTO generated_tiles (scheme, region, z, x, y, encoding, roofs, \
             data_version, west, south, east, north, bytes, etag, created_at, size, last_used) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17) \
             ON CONFLICT (scheme, region, z, x, y, encoding, roofs, data_version) DO UPDATE SET \
             bytes = EXCLUDED.bytes, etag = EXCLUDED.etag, created_at = EXCLUDED.created_at, \
             size = EXCLUDED.size, last_used = EXCLUDED.last_used";
        bind_key(sqlx::query(sql), key, data_version)
            .bind(b.min_lon())
            .bind(b.min_lat())
            .bind(b.max_lon())
            .bind(b.max_lat())
            .bind(bytes.to_vec())
            .bind(etag.to_owned())
            .bind(now / 1000)
            .bind(bytes.len() as i64 + ROW_OVERHEAD)
            .bind(now)
            .execute(&self.pool)
            .await?;
        self.evict_if_over().await
    }

    /// Past the bound, deletes the least recently used tiles, 32 at a time, down to 80 % of it
    /// (as the SQLite store does).
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        let mut used = self.used_bytes().await?;
        if used <= self.max_bytes {
            return Ok(());
        }
        let target = (self.max_bytes as f64 * 0.8) as u64;
        while used > target {
            let freed: Vec<i64> = sqlx::query(
                "DELETE FROM generated_tiles WHERE ctid IN (SELECT ctid FROM generated_tiles \
                 ORDER BY last_used LIMIT 32) RETURNING size",
            )
            .fetch_all(&self.pool)
            .await?
            .iter()
            .map(|r| r.get(0))
            .collect();
            if freed.is_empty() {
                break;
            }
            used = used.saturating_sub(freed.iter().map(|&s| s.max(0) as u64).sum());
        }
        Ok(())
    }

    /// Deletes one key's row, if stored.
    pub async fn remove(&self, key: &TileKey, data_version: &str) -> Result<(), sqlx::Error> {
        let sql = concat!("DELETE FROM generated_tiles WHERE ", key_where!());
        bind_key(sqlx::query(sql), key, data_version)
            .execute(&self.pool)
            .await?;
        Ok(())
    }

    /// Deletes every stored tile whose ground overlaps `area`; answers how many.
    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        Ok(sqlx::query(
            "DELETE FROM generated_tiles WHERE west <= $1 AND east >= $2 AND south <= $3 \
             AND north >= $4",
        )
        .bind(area.max_lon())
        .bind(area.min_lon())
        .bind(area.max_lat())
        .bind(area.min_lat())
        .execute(&self.pool)
        .await?
        .rows_affected())
    }
}

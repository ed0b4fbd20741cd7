//! The data tiles' statements on PostgreSQL.

use super::{DataOrigin, StoredDataTile, stored_of};
use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use sqlx::{PgPool, Row};
use std::collections::HashMap;

pub(super) async fn write_uses(
    pool: &PgPool,
    uses: &HashMap<TileCoord, i64>,
) -> Result<(), sqlx::Error> {
    let mut tx = pool.begin().await?;
    for (t, at) in uses {
        sqlx::query(
            "UPDATE osm_data_tiles SET last_used = GREATEST(last_used, $1) WHERE z = $2 AND x = $3 \
             AND y = $4",
        )
        .bind(*at)
        .bind(i64::from(t.z))
        .bind(i64::from(t.x))
        .bind(i64::from(t.y))
        .execute(&mut *tx)
        .await?;
    }
    tx.commit().await
}

pub(super) async fn overpass_bytes(pool: &PgPool) -> Result<i64, sqlx::Error> {
    sqlx::query(
        "SELECT COALESCE(SUM(size), 0)::BIGINT FROM osm_data_tiles WHERE source = 'overpass'",
    )
    .fetch_one(pool)
    .await
    .map(|r| r.get(0))
}

pub(super) async fn evict_least_used(pool: &PgPool) -> Result<Vec<i64>, sqlx::Error> {
    Ok(sqlx::query(
        "DELETE FROM osm_data_tiles WHERE (z, x, y) IN (SELECT z, x, y FROM osm_data_tiles \
         WHERE source = 'overpass' ORDER BY last_used, z, x, y LIMIT 1 FOR UPDATE SKIP LOCKED) \
         RETURNING size",
    )
    .fetch_all(pool)
    .await?
    .iter()
    .map(|r| r.get(0))
    .collect())
}

pub(super) async fn get(
    pool: &PgPool,
    t: &TileCoord,
) -> Result<Option<StoredDataTile>, sqlx::Error> {
    let row = sqlx::query(
        "SELECT body, hash, source, fetched_at FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3",
    )
    .bind(i64::from(t.z))
    .bind(i64::from(t.x))
    .bind(i64::from(t.y))
    .fetch_optional(pool)
    .await?;
    Ok(row.map(|r| {
        stored_of(
            Bytes::from(r.get::<Vec<u8>, _>(0)),
            r.get(1),
            &r.get::<String, _>(2),
            r.get(3),
        )
    }))
}

/// Stores the row in its own transaction; answers the hash it replaced.
pub(super) async fn put(
    pool: &PgPool,
    t: &TileCoord,
    body: &[u8],
    hash: &str,
    origin: DataOrigin,
    now_secs: i64,
) -> Result<Option<String>, sqlx::Error> {
    let mut tx = pool.begin().await?;
    let previous = put_in(&mut tx, t, body, hash, origin, now_secs).await?;
    tx.commit().await?;
    Ok(previous)
}

/// Stores the row in the caller's transaction; answers the hash it replaced.
pub(super) async fn put_in(
    tx: &mut sqlx::PgConnection,
    t: &TileCoord,
    body: &[u8],
    hash: &str,
    origin: DataOrigin,
    now_secs: i64,
) -> Result<Option<String>, sqlx::Error> {
    let previous: Option<String> = sqlx::query(
        "SELECT hash FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3 FOR UPDATE",
    )
    .bind(i64::from(t.z))
    .bind(i64::from(t.x))
    .bind(i64::from(t.y))
    .fetch_optional(&mut *tx)
    .await?
    .map(|r| r.get(0));
    sqlx::query(
        "INSERT INTO osm_data_tiles (z, x, y, body, hash, source, fetched_at, size, last_used) \
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) ON CONFLICT (z, x, y) DO UPDATE SET \
         body = EXCLUDED.body, hash = EXCLUDED.hash, source = EXCLUDED.source, \
         fetched_at = EXCLUDED.fetched_at, size = EXCLUDED.size, last_used = EXCLUDED.last_used",
    )
    .bind(i64::from(t.z))
    .bind(i64::from(t.x))
    .bind(i64::from(t.y))
    .bind(body)
    .bind(hash)
    .bind(origin.as_str())
    .bind(now_secs)
    .bind(i64::try_from(body.len()).unwrap_or(i64::MAX))
    .bind(now_secs.saturating_mul(1000))
    .execute(&mut *tx)
    .await?;
    Ok(previous)
}

pub(super) async fn count(pool: &PgPool) -> Result<i64, sqlx::Error> {
    sqlx::query("SELECT COUNT(*) FROM osm_data_tiles")
        .fetch_one(pool)
        .await
        .map(|r| r.get(0))
}

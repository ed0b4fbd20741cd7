//! The data tiles' statements on SQLite.

use super::{DataOrigin, StoredDataTile, stored_of};
use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use sqlx::{Row, SqlitePool};
use std::collections::HashMap;

pub(super) async fn write_uses(
    pool: &SqlitePool,
    uses: &HashMap<TileCoord, i64>,
) -> Result<(), sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
    for (t, at) in uses {
        sqlx::query(
            "UPDATE osm_data_tiles SET last_used = MAX(last_used, ?) WHERE z = ? AND x = ? AND y = ?",
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

pub(super) async fn overpass_bytes(pool: &SqlitePool) -> Result<i64, sqlx::Error> {
    sqlx::query("SELECT COALESCE(SUM(size), 0) FROM osm_data_tiles WHERE source = 'overpass'")
        .fetch_one(pool)
        .await
        .map(|r| r.get(0))
}

pub(super) async fn evict_least_used(pool: &SqlitePool) -> Result<Vec<i64>, sqlx::Error> {
    Ok(sqlx::query(
        "DELETE FROM osm_data_tiles WHERE rowid IN (SELECT rowid FROM osm_data_tiles \
         WHERE source = 'overpass' ORDER BY last_used, rowid LIMIT 1) RETURNING size",
    )
    .fetch_all(pool)
    .await?
    .iter()
    .map(|r| r.get(0))
    .collect())
}

pub(super) async fn get(
    pool: &SqlitePool,
    t: &TileCoord,
) -> Result<Option<StoredDataTile>, sqlx::Error> {
    let row = sqlx::query(
        "SELECT body, hash, source, fetched_at FROM osm_data_tiles WHERE z = ? AND x = ? AND y = ?",
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
    pool: &SqlitePool,
    t: &TileCoord,
    body: &[u8],
    hash: &str,
    origin: DataOrigin,
    now_secs: i64,
) -> Result<Option<String>, sqlx::Error> {
    let mut tx = pool.begin_with("BEGIN IMMEDIATE").await?;
    let previous = put_in(&mut tx, t, body, hash, origin, now_secs).await?;
    tx.commit().await?;
    Ok(previous)
}

/// Stores the row in the caller's transaction; answers the hash it replaced.
pub(super) async fn put_in(
    tx: &mut sqlx::SqliteConnection,
    t: &TileCoord,
    body: &[u8],
    hash: &str,
    origin: DataOrigin,
    now_secs: i64,
) -> Result<Option<String>, sqlx::Error> {
    let previous: Option<String> =
        sqlx::query("SELECT hash FROM osm_data_tiles WHERE z = ? AND x = ? AND y = ?")
            .bind(i64::from(t.z))
            .bind(i64::from(t.x))
            .bind(i64::from(t.y))
            .fetch_optional(&mut *tx)
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
    .bind(hash)
    .bind(origin.as_str())
    .bind(now_secs)
    .bind(i64::try_from(body.len()).unwrap_or(i64::MAX))
    .bind(now_secs.saturating_mul(1000))
    .execute(&mut *tx)
    .await?;
    Ok(previous)
}

pub(super) async fn count(pool: &SqlitePool) -> Result<i64, sqlx::Error> {
    sqlx::query("SELECT COUNT(*) FROM osm_data_tiles")
        .fetch_one(pool)
        .await
        .map(|r| r.get(0))
}

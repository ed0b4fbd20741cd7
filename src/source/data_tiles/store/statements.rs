//! The data tiles' statements, each written once for both backends (`$n` placeholders, which
//! SQLite takes too, and `ON CONFLICT`), compiled for each pool by `on_pool!`; [`Dialect`] holds
//! the real differences: how a write starts, the larger of two values, and how the least used
//! row is picked for eviction (PostgreSQL skips rows another replica is deleting).

use super::{DataOrigin, StoredDataTile, stored_of};
use crate::db::{BeginWrite as _, Database, on_pool};
use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use sqlx::Row;
use std::collections::HashMap;

/// The statements whose SQL differs between the backends.
struct Dialect {
    /// Moves a tile's last use forward (the larger of two values: `MAX` or `GREATEST`).
    write_use: &'static str,
    /// Deletes the least recently used Overpass tile (PostgreSQL skips rows another replica is
    /// deleting).
    evict: &'static str,
    /// The hash a put replaces (PostgreSQL locks the row until the transaction ends).
    previous_hash: &'static str,
}

const SQLITE: Dialect = Dialect {
    write_use: "UPDATE osm_data_tiles SET last_used = MAX(last_used, $1) \
                WHERE z = $2 AND x = $3 AND y = $4",
    evict: "DELETE FROM osm_data_tiles WHERE rowid IN (SELECT rowid FROM osm_data_tiles \
            WHERE source = 'overpass' ORDER BY last_used, rowid LIMIT 1) RETURNING size",
    previous_hash: "SELECT hash FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3",
};

const POSTGRES: Dialect = Dialect {
    write_use: "UPDATE osm_data_tiles SET last_used = GREATEST(last_used, $1) \
                WHERE z = $2 AND x = $3 AND y = $4",
    evict: "DELETE FROM osm_data_tiles WHERE (z, x, y) IN (SELECT z, x, y FROM osm_data_tiles \
            WHERE source = 'overpass' ORDER BY last_used, z, x, y LIMIT 1 \
            FOR UPDATE SKIP LOCKED) RETURNING size",
    previous_hash: "SELECT hash FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3 \
                    FOR UPDATE",
};

fn dialect(db: &Database) -> &'static Dialect {
    match db {
        Database::Sqlite(_) => &SQLITE,
        Database::Postgres(_) => &POSTGRES,
    }
}

/// Writes the uses noted since the last write, each only forward in time.
pub(super) async fn write_uses(
    db: &Database,
    uses: &HashMap<TileCoord, i64>,
) -> Result<(), sqlx::Error> {
    let sql = dialect(db).write_use;
    on_pool!(db, pool => {
        let mut tx = pool.begin_write().await?;
        for (t, at) in uses {
            sqlx::query(sql)
                .bind(*at)
                .bind(i64::from(t.z))
                .bind(i64::from(t.x))
                .bind(i64::from(t.y))
                .execute(&mut *tx)
                .await?;
        }
        tx.commit().await
    })
}

/// Bytes of stored Overpass data.
pub(super) async fn overpass_bytes(db: &Database) -> Result<i64, sqlx::Error> {
    let sql = "SELECT CAST(COALESCE(SUM(size), 0) AS BIGINT) FROM osm_data_tiles \
               WHERE source = 'overpass'";
    on_pool!(db, pool => sqlx::query(sql).fetch_one(pool).await.map(|r| r.get(0)))
}

/// Deletes the least recently used Overpass tile; answers its size (none when there is none).
pub(super) async fn evict_least_used(db: &Database) -> Result<Vec<i64>, sqlx::Error> {
    let sql = dialect(db).evict;
    let rows = on_pool!(db, pool => sqlx::query(sql)
        .fetch_all(pool)
        .await?
        .iter()
        .map(|r| r.get(0))
        .collect());
    Ok(rows)
}

pub(super) async fn get(
    db: &Database,
    t: &TileCoord,
) -> Result<Option<StoredDataTile>, sqlx::Error> {
    let sql = "SELECT body, hash, source, fetched_at FROM osm_data_tiles \
               WHERE z = $1 AND x = $2 AND y = $3";
    on_pool!(db, pool => {
        let row = sqlx::query(sql)
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
    })
}

/// The two statements of a put on connection `$conn`: the hash it replaces (its row locked by
/// the dialect's `$previous_hash`), then the row.
macro_rules! put_row {
    ($conn:expr, $row:expr, $previous_hash:expr) => {{
        let row: &NewRow<'_> = $row;
        let previous: Option<String> = sqlx::query($previous_hash)
        .bind(i64::from(row.t.z))
        .bind(i64::from(row.t.x))
        .bind(i64::from(row.t.y))
        .fetch_optional(&mut *$conn)
        .await?
        .map(|r| r.get(0));
        sqlx::query(
            "INSERT INTO osm_data_tiles (z, x, y, body, hash, source, fetched_at, size, \
             last_used) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) ON CONFLICT (z, x, y) DO \
             UPDATE SET body = excluded.body, hash = excluded.hash, source = excluded.source, \
             fetched_at = excluded.fetched_at, size = excluded.size, last_used = excluded.last_used",
        )
        .bind(i64::from(row.t.z))
        .bind(i64::from(row.t.x))
        .bind(i64::from(row.t.y))
        .bind(row.body)
        .bind(row.hash)
        .bind(row.origin.as_str())
        .bind(row.now_secs)
        .bind(i64::try_from(row.body.len()).unwrap_or(i64::MAX))
        .bind(row.now_secs.saturating_mul(1000))
        .execute(&mut *$conn)
        .await?;
        previous
    }};
}

/// A data tile to store.
pub(super) struct NewRow<'a> {
    pub t: &'a TileCoord,
    pub body: &'a [u8],
    pub hash: &'a str,
    pub origin: DataOrigin,
    pub now_secs: i64,
}

/// Stores the row in its own transaction; answers the hash it replaced.
pub(super) async fn put(db: &Database, row: &NewRow<'_>) -> Result<Option<String>, sqlx::Error> {
    let previous_hash = dialect(db).previous_hash;
    on_pool!(db, pool => {
        let mut tx = pool.begin_write().await?;
        let previous = put_row!(&mut *tx, row, previous_hash);
        tx.commit().await?;
        Ok(previous)
    })
}

/// Stores the rows in the caller's transaction (see `ImportWriter`); answers the hash each
/// replaced. PostgreSQL takes them in two statements (arrays, `UNNEST`) whatever their number;
/// SQLite, in the process, one row at a time.
pub(super) async fn put_many_in(
    tx: &mut super::ImportTx,
    rows: &[NewRow<'_>],
) -> Result<Vec<Option<String>>, sqlx::Error> {
    match tx {
        super::ImportTx::Sqlite(tx) => {
            let mut previous = Vec::with_capacity(rows.len());
            for row in rows {
                previous.push(put_row!(&mut **tx, row, SQLITE.previous_hash));
            }
            Ok(previous)
        }
        super::ImportTx::Postgres(tx) => {
            let column = |f: fn(&NewRow<'_>) -> i64| rows.iter().map(f).collect::<Vec<i64>>();
            let (z, x, y) = (
                column(|r| i64::from(r.t.z)),
                column(|r| i64::from(r.t.x)),
                column(|r| i64::from(r.t.y)),
            );
            let held: Vec<(i64, i64, i64, String)> = sqlx::query_as(
                "SELECT t.z, t.x, t.y, t.hash FROM osm_data_tiles t \
                 JOIN UNNEST($1::int8[], $2::int8[], $3::int8[]) AS u(z, x, y) \
                 ON t.z = u.z AND t.x = u.x AND t.y = u.y FOR UPDATE OF t",
            )
            .bind(&z)
            .bind(&x)
            .bind(&y)
            .fetch_all(&mut **tx)
            .await?;
            let held: HashMap<(i64, i64, i64), String> = held
                .into_iter()
                .map(|(z, x, y, h)| ((z, x, y), h))
                .collect();
            sqlx::query(
                "INSERT INTO osm_data_tiles (z, x, y, body, hash, source, fetched_at, size, \
                 last_used) SELECT * FROM UNNEST($1::int8[], $2::int8[], $3::int8[], \
                 $4::bytea[], $5::text[], $6::text[], $7::int8[], $8::int8[], $9::int8[]) \
                 ON CONFLICT (z, x, y) DO UPDATE SET body = excluded.body, \
                 hash = excluded.hash, source = excluded.source, \
                 fetched_at = excluded.fetched_at, size = excluded.size, \
                 last_used = excluded.last_used",
            )
            .bind(&z)
            .bind(&x)
            .bind(&y)
            .bind(rows.iter().map(|r| r.body).collect::<Vec<&[u8]>>())
            .bind(rows.iter().map(|r| r.hash).collect::<Vec<&str>>())
            .bind(
                rows.iter()
                    .map(|r| r.origin.as_str())
                    .collect::<Vec<&str>>(),
            )
            .bind(column(|r| r.now_secs))
            .bind(column(|r| i64::try_from(r.body.len()).unwrap_or(i64::MAX)))
            .bind(column(|r| r.now_secs.saturating_mul(1000)))
            .execute(&mut **tx)
            .await?;
            Ok(rows
                .iter()
                .map(|r| {
                    held.get(&(i64::from(r.t.z), i64::from(r.t.x), i64::from(r.t.y)))
                        .cloned()
                })
                .collect())
        }
    }
}

/// Whether a data tile is stored (its body is not read).
pub(super) async fn holds(db: &Database, t: &TileCoord) -> Result<bool, sqlx::Error> {
    let sql = "SELECT 1 FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3";
    on_pool!(db, pool => {
        let row = sqlx::query(sql)
            .bind(i64::from(t.z))
            .bind(i64::from(t.x))
            .bind(i64::from(t.y))
            .fetch_optional(pool)
            .await?;
        Ok(row.is_some())
    })
}

pub(super) async fn count(db: &Database) -> Result<i64, sqlx::Error> {
    let sql = "SELECT COUNT(*) FROM osm_data_tiles";
    on_pool!(db, pool => sqlx::query(sql).fetch_one(pool).await.map(|r| r.get(0)))
}

/// Every stored data tile's coordinates.
pub(super) async fn stored_tiles(db: &Database) -> Result<Vec<TileCoord>, sqlx::Error> {
    let sql = "SELECT z, x, y FROM osm_data_tiles ORDER BY z, x, y";
    let rows: Vec<(i64, i64, i64)> = on_pool!(db, pool => sqlx::query(sql)
        .fetch_all(pool)
        .await?
        .iter()
        .map(|r| (r.get(0), r.get(1), r.get(2)))
        .collect());
    Ok(rows
        .into_iter()
        .filter_map(|(z, x, y)| {
            TileCoord::new(
                u32::try_from(z).ok()?,
                u32::try_from(x).ok()?,
                u32::try_from(y).ok()?,
            )
            .ok()
        })
        .collect())
}

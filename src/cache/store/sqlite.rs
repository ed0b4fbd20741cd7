//! The generated tiles on SQLite (one machine): under typed keys, so they survive a restart,
//! bounded in bytes: past the bound the least recently used tiles are evicted.
//!
//! A read only reads: which rows were used is noted in memory and written in one transaction
//! off the request path (before an eviction, or when many are noted), so a cached tile never
//! waits on, or fails because of, the database's writers. The notes are best-effort: a crash
//! loses the order of recent use, never a tile.

use super::{StoredTile, columns};
use crate::cache::key::TileKey;
use crate::clock::Clock;
use crate::db::UseNotes;
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use sqlx::{Row, SqlitePool};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Eviction goes down to this share of the bound, so it does not run on every write and the file
/// (pages freed by eviction are reused, not returned) stays near the bound.
const EVICT_TO: f64 = 0.8;
/// What a row costs on disk beyond its bytes, estimated: SQLite keeps a blob in 4 KB pages, so on
/// average half a page is slack, plus the row's key and header (measured: a store of 17 MB of
/// tiles made a 26 MB file without it).
const ROW_OVERHEAD: i64 = 2_560;
/// Tiles deleted per eviction statement.
const EVICT_BATCH: i64 = 32;
/// Uses noted before they are written (further ones start a write at once).
const MAX_NOTED_USES: usize = 4_096;

#[derive(Clone)]
pub struct SqliteTileStore {
    pool: SqlitePool,
    /// Bytes of stored tiles at most (`u64::MAX`: unbounded).
    max_bytes: u64,
    /// Bytes of stored tiles now.
    used: Arc<AtomicU64>,
    /// One eviction at a time.
    evicting: Arc<tokio::sync::Mutex<()>>,
    /// Rows read since their uses were last written.
    uses: Arc<UseNotes<(TileKey, String)>>,
    /// What writes and uses are stamped with.
    clock: Clock,
}

/// The condition that selects one key's row; [`bind_key`] binds its values in this order.
macro_rules! key_where {
    () => {
        "scheme = ? AND region = ? AND z = ? AND x = ? AND y = ? AND encoding = ? AND roofs = ? \
         AND data_version = ?"
    };
}

type Query<'q> = sqlx::query::Query<'q, sqlx::Sqlite, sqlx::sqlite::SqliteArguments>;

/// Binds a key's columns, in the order of `key_where!`.
fn bind_key<'q>(query: Query<'q>, key: &'q TileKey, data_version: &'q str) -> Query<'q> {
    let (scheme, region, z, x, y) = columns(key);
    query
        .bind(scheme)
        .bind(region)
        .bind(z)
        .bind(x)
        .bind(y)
        .bind(key.encoding.as_str())
        .bind(key.roofs.name())
        .bind(data_version)
}

impl SqliteTileStore {
    /// The store with writes and uses stamped by `clock`.
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// An unbounded store (for `citymesh import`, which only deletes).
    pub fn new(pool: SqlitePool) -> Self {
        Self {
            pool,
            max_bytes: u64::MAX,
            used: Arc::new(AtomicU64::new(0)),
            evicting: Arc::new(tokio::sync::Mutex::new(())),
            uses: Arc::new(UseNotes::new(MAX_NOTED_USES)),
            clock: Clock::system(),
        }
    }

    /// A store bounded to `max_bytes`, counting what is stored already (and evicting down to
    /// the bound if a smaller one was given than last time).
    pub async fn bounded(pool: SqlitePool, max_bytes: u64) -> Result<Self, sqlx::Error> {
        let used: i64 = sqlx::query("SELECT COALESCE(SUM(size), 0) FROM generated_tiles")
            .fetch_one(&pool)
            .await?
            .get(0);
        let store = Self {
            max_bytes,
            used: Arc::new(AtomicU64::new(u64::try_from(used).unwrap_or(0))),
            ..Self::new(pool)
        };
        store.evict_if_over().await?;
        Ok(store)
    }

    /// Bytes of stored tiles.
    pub fn used_bytes(&self) -> u64 {
        self.used.load(Ordering::Relaxed)
    }

    /// The stored tile; its use is noted, and written later.
    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        let query = sqlx::query(concat!(
            "SELECT bytes, etag FROM generated_tiles WHERE ",
            key_where!()
        ));
        let row = bind_key(query, key, data_version)
            .fetch_optional(&self.pool)
            .await?;
        if row.is_some() {
            self.note_use(key, data_version);
        }
        Ok(row.map(|row| StoredTile {
            bytes: Bytes::from(row.get::<Vec<u8>, _>(0)),
            etag: row.get(1),
        }))
    }

    fn note_use(&self, key: &TileKey, data_version: &str) {
        if self
            .uses
            .note((*key, data_version.to_owned()), self.clock.now_ms())
        {
            let store = self.clone();
            tokio::spawn(async move { store.write_uses().await });
        }
    }

    /// Writes the noted uses in one transaction; on failure they are dropped (best-effort).
    pub async fn write_uses(&self) {
        let uses = self.uses.take();
        if uses.is_empty() {
            return;
        }
        let result = async {
            let mut tx = self.pool.begin_with("BEGIN IMMEDIATE").await?;
            for ((key, data_version), at) in &uses {
                let query = sqlx::query(concat!(
                    "UPDATE generated_tiles SET last_used = MAX(last_used, ?) WHERE ",
                    key_where!()
                ))
                .bind(*at);
                bind_key(query, key, data_version).execute(&mut *tx).await?;
            }
            tx.commit().await
        }
        .await;
        if let Err(e) = result {
            tracing::debug!(uses = uses.len(), "tile uses not written: {e}");
        }
    }

    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
    ) -> Result<(), sqlx::Error> {
        let b = key.tile.bounds();
        let now = self.clock.now_ms();
        let cost = bytes.len() as i64 + ROW_OVERHEAD;
        // Replacing a row: its cost leaves the count first.
        self.remove(key, data_version).await?;
        let insert = sqlx::query(
            "INSERT INTO generated_tiles (scheme, region, z, x, y, encoding, roofs, data_version, \
             west, south, east, north, bytes, etag, created_at, size, last_used) \
             VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
        );
        bind_key(insert, key, data_version)
            .bind(b.min_lon())
            .bind(b.min_lat())
            .bind(b.max_lon())
            .bind(b.max_lat())
            .bind(bytes)
            .bind(etag)
            .bind(now / 1000)
            .bind(cost)
            .bind(now)
            .execute(&self.pool)
            .await?;
        self.used.fetch_add(cost as u64, Ordering::Relaxed);
        self.evict_if_over().await
    }

    fn forget(&self, size: i64) {
        let size = u64::try_from(size).unwrap_or(0);
        let _ = self
            .used
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |u| {
                Some(u.saturating_sub(size))
            });
    }

    /// Past the bound, deletes the least recently used tiles down to 80 % of it.
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        if self.used_bytes() <= self.max_bytes {
            return Ok(());
        }
        let _one = self.evicting.lock().await;
        // The order of use must be known before choosing what to evict.
        self.write_uses().await;
        let target = (self.max_bytes as f64 * EVICT_TO) as u64;
        let mut evicted = 0u64;
        while self.used_bytes() > target {
            let sizes: Vec<i64> = sqlx::query(
                "DELETE FROM generated_tiles WHERE rowid IN (SELECT rowid FROM generated_tiles \
                 ORDER BY last_used LIMIT ?) RETURNING size",
            )
            .bind(EVICT_BATCH)
            .fetch_all(&self.pool)
            .await?
            .iter()
            .map(|r| r.get(0))
            .collect();
            if sizes.is_empty() {
                // Nothing left to evict: the count drifted; start again from zero.
                self.used.store(0, Ordering::Relaxed);
                break;
            }
            evicted += sizes.len() as u64;
            sizes.into_iter().for_each(|s| self.forget(s));
        }
        tracing::debug!(
            evicted,
            used = self.used_bytes(),
            "tile store evicted least recently used tiles"
        );
        Ok(())
    }

    /// Deletes every stored tile (any scheme, encoding or version) whose ground overlaps `area`.
    /// Deletes one key's row, if stored.
    pub async fn remove(&self, key: &TileKey, data_version: &str) -> Result<(), sqlx::Error> {
        let removed: Option<i64> = bind_key(
            sqlx::query(concat!(
                "DELETE FROM generated_tiles WHERE ",
                key_where!(),
                " RETURNING size"
            )),
            key,
            data_version,
        )
        .fetch_optional(&self.pool)
        .await?
        .map(|r| r.get(0));
        if let Some(size) = removed {
            self.forget(size);
        }
        Ok(())
    }

    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        let sizes: Vec<i64> = sqlx::query(
            "DELETE FROM generated_tiles WHERE west <= ? AND east >= ? AND south <= ? AND north >= ? \
             RETURNING size",
        )
        .bind(area.max_lon())
        .bind(area.min_lon())
        .bind(area.max_lat())
        .bind(area.min_lat())
        .fetch_all(&self.pool)
        .await?
        .iter()
        .map(|r| r.get(0))
        .collect();
        let removed = sizes.len() as u64;
        sizes.into_iter().for_each(|s| self.forget(s));
        Ok(removed)
    }
}

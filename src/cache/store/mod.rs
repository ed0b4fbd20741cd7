//! The stored level of the tile cache: generated content under typed keys, so it survives a
//! restart, bounded in bytes (past the bound the least recently used tiles are evicted), on the
//! database the server was given: SQLite on one machine, PostgreSQL shared by replicas. Each
//! statement is written once (`$n` placeholders and `ON CONFLICT` read the same on both) and
//! run by `on_pool!`; [`Dialect`] holds the two that differ, and `replicas.rs` what only
//! PostgreSQL does (one generation per tile across replicas, data changes announced).
//!
//! A read only reads: which rows were used is noted in memory and written in one transaction
//! off the request path (before an eviction, or when many are noted), so a cached tile never
//! waits on, or fails because of, the database's writers. The notes are best-effort: a crash
//! loses the order of recent use, never a tile.

/// Binds a key's columns as `$1` to `$8`, in the order of [`KEY_WHERE`].
macro_rules! bind_key {
    ($query:expr, $key:expr, $data_version:expr) => {{
        let key: &$crate::cache::key::TileKey = $key;
        let (scheme, region, z, x, y) = $crate::cache::store::columns(key);
        $query
            .bind(scheme)
            .bind(region)
            .bind(z)
            .bind(x)
            .bind(y)
            .bind(key.encoding.as_str())
            .bind(key.content_name())
            .bind($data_version)
    }};
}

mod replicas;
mod summaries;

pub use replicas::{DATA_CHANGED_CHANNEL, DataChangedNote, GenerationLock};

use super::key::{TileId, TileKey};
use crate::clock::Clock;
use crate::db::{BeginWrite as _, Database, UseNotes, on_pool};
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Eviction goes down to this share of the bound, so it does not run on every write and the
/// file (pages freed by eviction are reused, not returned) stays near the bound.
const EVICT_TO: f64 = 0.8;
/// What a row costs beyond its bytes, estimated: SQLite keeps a blob in 4 KB pages, so on
/// average half a page is slack, plus the row's key and header (measured: a store of 17 MB of
/// tiles made a 26 MB file without it); PostgreSQL's TOAST pages and row header about the same.
const ROW_OVERHEAD: i64 = 2_560;
/// Tiles deleted per eviction statement.
const EVICT_BATCH: i64 = 32;
/// Uses noted before they are written (further ones start a write at once).
const MAX_NOTED_USES: usize = 4_096;
/// Writes between two exact counts of the stored bytes (other replicas write too).
const RECOUNT_EVERY: u64 = 512;

/// The condition that selects one key's row; `bind_key!` binds `$1` to `$8`.
macro_rules! key_where {
    () => {
        "scheme = $1 AND region = $2 AND z = $3 AND x = $4 AND y = $5 AND encoding = $6 \
         AND roofs = $7 AND data_version = $8"
    };
}

const SELECT_TILE: &str = concat!(
    "SELECT bytes, etag FROM generated_tiles WHERE ",
    key_where!()
);
const SELECT_SIZE: &str = concat!("SELECT size FROM generated_tiles WHERE ", key_where!());
const DELETE_TILE: &str = concat!(
    "DELETE FROM generated_tiles WHERE ",
    key_where!(),
    " RETURNING size"
);
const UPSERT_TILE: &str = "INSERT INTO generated_tiles (scheme, region, z, x, y, encoding, \
    roofs, data_version, west, south, east, north, bytes, etag, created_at, size, last_used) \
    VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17) \
    ON CONFLICT (scheme, region, z, x, y, encoding, roofs, data_version) DO UPDATE SET \
    bytes = excluded.bytes, etag = excluded.etag, created_at = excluded.created_at, \
    size = excluded.size, last_used = excluded.last_used";
const COUNT_BYTES: &str = "SELECT CAST(COALESCE(SUM(size), 0) AS BIGINT) FROM generated_tiles";
const DELETE_OVERLAPPING: &str = "DELETE FROM generated_tiles WHERE west <= $1 AND east >= $2 \
    AND south <= $3 AND north >= $4 RETURNING size";

/// The statements whose SQL differs between the backends.
struct Dialect {
    /// Moves a row's last use forward (the larger of two values: `MAX` or `GREATEST`).
    write_use: &'static str,
    /// Deletes the least recently used tiles (PostgreSQL skips rows another replica is
    /// deleting).
    evict: &'static str,
    /// Whether a deletion over an area is announced to other replicas.
    announces_changes: bool,
}

const SQLITE: Dialect = Dialect {
    write_use: concat!(
        "UPDATE generated_tiles SET last_used = MAX(last_used, $9) WHERE ",
        key_where!()
    ),
    evict: "DELETE FROM generated_tiles WHERE rowid IN (SELECT rowid FROM generated_tiles \
            ORDER BY last_used LIMIT $1) RETURNING size",
    announces_changes: false,
};

const POSTGRES: Dialect = Dialect {
    write_use: concat!(
        "UPDATE generated_tiles SET last_used = GREATEST(last_used, $9) WHERE ",
        key_where!()
    ),
    evict: "DELETE FROM generated_tiles WHERE ctid IN (SELECT ctid FROM generated_tiles \
            ORDER BY last_used LIMIT $1 FOR UPDATE SKIP LOCKED) RETURNING size",
    announces_changes: true,
};

/// A stored tile: its bytes and their ETag.
#[derive(Debug, Clone)]
pub struct StoredTile {
    pub bytes: Bytes,
    pub etag: String,
}

impl From<(Vec<u8>, String)> for StoredTile {
    fn from((bytes, etag): (Vec<u8>, String)) -> Self {
        Self {
            bytes: Bytes::from(bytes),
            etag,
        }
    }
}

/// What a miss should do, decided across processes sharing the store.
pub enum GenerationTurn {
    /// Generate the tile (holding `lock` when the store coordinates processes).
    Generate {
        lock: Option<GenerationLock>,
        /// Another process held the key's lock first.
        waited: bool,
        /// ... and did not finish within the wait.
        timed_out: bool,
    },
    /// Another process generated it meanwhile.
    Stored { tile: StoredTile, waited: bool },
}

/// The generated tiles on the opened database.
#[derive(Clone)]
pub struct TileStore {
    db: Database,
    /// Bytes of stored tiles at most (`u64::MAX`: unbounded).
    max_bytes: u64,
    /// Who this replica is, in the notifications it sends.
    replica: Arc<str>,
    /// Bytes stored, as last counted plus this process's writes since.
    used: Arc<AtomicU64>,
    /// Writes since the store was opened (every [`RECOUNT_EVERY`] the bytes are counted again).
    writes: Arc<AtomicU64>,
    /// One eviction at a time.
    evicting: Arc<tokio::sync::Mutex<()>>,
    /// Rows read since their uses were last written.
    uses: Arc<UseNotes<(TileKey, String)>>,
    /// What writes and uses are stamped with.
    clock: Clock,
}

impl TileStore {
    /// The store on `db`, bounded to `max_bytes` (`u64::MAX`: unbounded), announcing data
    /// changes as `replica`; counts what is stored already (and evicts down to the bound if a
    /// smaller one was given than last time).
    pub async fn open(db: &Database, max_bytes: u64, replica: &str) -> Result<Self, sqlx::Error> {
        let store = Self {
            db: db.clone(),
            max_bytes,
            replica: Arc::from(replica),
            used: Arc::new(AtomicU64::new(0)),
            writes: Arc::new(AtomicU64::new(0)),
            evicting: Arc::new(tokio::sync::Mutex::new(())),
            uses: Arc::new(UseNotes::new(MAX_NOTED_USES)),
            clock: Clock::system(),
        };
        store.recount().await?;
        store.evict_if_over().await?;
        Ok(store)
    }

    /// The store with writes and uses stamped by `clock` (tests move a manual one).
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// `sqlite` or `postgres`.
    pub fn backend(&self) -> &'static str {
        self.db.backend()
    }

    fn dialect(&self) -> &'static Dialect {
        match self.db {
            Database::Sqlite(_) => &SQLITE,
            Database::Postgres(_) => &POSTGRES,
        }
    }

    /// Counts the stored bytes exactly (every replica's).
    async fn recount(&self) -> Result<u64, sqlx::Error> {
        let used: i64 =
            on_pool!(&self.db, pool => sqlx::query_scalar(COUNT_BYTES).fetch_one(pool).await?);
        let used = u64::try_from(used).unwrap_or(0);
        self.used.store(used, Ordering::Relaxed);
        Ok(used)
    }

    /// Bytes of stored tiles, as last counted plus this process's writes since.
    pub fn used_bytes(&self) -> u64 {
        self.used.load(Ordering::Relaxed)
    }

    /// The stored tile; its use is noted and written later (a read never writes).
    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        let row: Option<(Vec<u8>, String)> = on_pool!(&self.db, pool => {
            bind_key!(sqlx::query_as(SELECT_TILE), key, data_version)
                .fetch_optional(pool)
                .await?
        });
        if row.is_some()
            && self
                .uses
                .note((*key, data_version.to_owned()), self.clock.now_ms())
        {
            let store = self.clone();
            tokio::spawn(async move { store.write_uses().await });
        }
        Ok(row.map(StoredTile::from))
    }

    /// Writes the noted uses in one transaction; on failure they are dropped (best-effort).
    pub async fn write_uses(&self) {
        let uses = self.uses.take();
        if uses.is_empty() {
            return;
        }
        let sql = self.dialect().write_use;
        let result: Result<(), sqlx::Error> = on_pool!(&self.db, pool => {
            async {
                let mut tx = pool.begin_write().await?;
                for ((key, data_version), at) in &uses {
                    bind_key!(sqlx::query(sql), key, data_version.as_str())
                        .bind(*at)
                        .execute(&mut *tx)
                        .await?;
                }
                tx.commit().await
            }
            .await
        });
        if let Err(e) = result {
            tracing::debug!(uses = uses.len(), "tile uses not written: {e}");
        }
    }

    /// Whose turn it is to generate a tile this process missed: on SQLite always this
    /// process's (one process owns the file); on PostgreSQL see [`replicas::turn`].
    pub async fn turn(
        &self,
        key: &TileKey,
        data_version: &str,
        wait: Duration,
    ) -> Result<GenerationTurn, sqlx::Error> {
        match &self.db {
            Database::Sqlite(_) => Ok(GenerationTurn::Generate {
                lock: None,
                waited: false,
                timed_out: false,
            }),
            Database::Postgres(pool) => replicas::turn(pool, key, data_version, wait).await,
        }
    }

    /// Stores a tile, replacing the key's row, inside the generation lock's transaction when
    /// held (committing it releases the waiting replicas), then evicts the least recently used
    /// tiles past the bound.
    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
        lock: Option<GenerationLock>,
    ) -> Result<(), sqlx::Error> {
        let b = key.tile.bounds();
        let now = self.clock.now_ms();
        let cost = bytes.len() as i64 + ROW_OVERHEAD;
        // The replaced row's size (read in the same transaction) leaves the count.
        macro_rules! put_row {
            ($tx:expr) => {{
                let replaced: Option<i64> =
                    bind_key!(sqlx::query_scalar(SELECT_SIZE), key, data_version)
                        .fetch_optional(&mut *$tx)
                        .await?;
                bind_key!(sqlx::query(UPSERT_TILE), key, data_version)
                    .bind(b.min_lon())
                    .bind(b.min_lat())
                    .bind(b.max_lon())
                    .bind(b.max_lat())
                    .bind(bytes)
                    .bind(etag)
                    .bind(now / 1000)
                    .bind(cost)
                    .bind(now)
                    .execute(&mut *$tx)
                    .await?;
                $tx.commit().await?;
                replaced.unwrap_or(0)
            }};
        }
        let replaced = match lock {
            Some(GenerationLock(mut tx)) => put_row!(tx),
            None => on_pool!(&self.db, pool => {
                let mut tx = pool.begin_write().await?;
                put_row!(tx)
            }),
        };
        self.forget(replaced);
        self.used.fetch_add(cost as u64, Ordering::Relaxed);
        if self.writes.fetch_add(1, Ordering::Relaxed) % RECOUNT_EVERY == RECOUNT_EVERY - 1 {
            self.recount().await?;
        }
        self.evict_if_over().await
    }

    /// Past the bound (counted exactly first: other replicas evict too), deletes the least
    /// recently used tiles, [`EVICT_BATCH`] at a time, down to 80 % of it.
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        if self.used_bytes() <= self.max_bytes {
            return Ok(());
        }
        let _one = self.evicting.lock().await;
        let mut used = self.recount().await?;
        if used <= self.max_bytes {
            return Ok(());
        }
        // The order of use must be known before choosing what to evict.
        self.write_uses().await;
        let target = (self.max_bytes as f64 * EVICT_TO) as u64;
        let sql = self.dialect().evict;
        let mut evicted = 0usize;
        while used > target {
            let freed: Vec<i64> = on_pool!(&self.db, pool => {
                sqlx::query_scalar(sql).bind(EVICT_BATCH).fetch_all(pool).await?
            });
            if freed.is_empty() {
                break;
            }
            evicted += freed.len();
            used = used.saturating_sub(freed.iter().map(|&s| s.max(0) as u64).sum());
        }
        self.used.store(used, Ordering::Relaxed);
        tracing::debug!(
            evicted,
            used,
            "tile store evicted least recently used tiles"
        );
        Ok(())
    }

    fn forget(&self, size: i64) {
        let size = u64::try_from(size).unwrap_or(0);
        let _ = self
            .used
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |u| {
                Some(u.saturating_sub(size))
            });
    }

    /// How many generated tiles are stored.
    pub async fn count(&self) -> Result<i64, sqlx::Error> {
        on_pool!(&self.db, pool => {
            sqlx::query_scalar("SELECT COUNT(*) FROM generated_tiles").fetch_one(pool).await
        })
    }

    /// Deletes one key's row, if stored.
    pub async fn remove(&self, key: &TileKey, data_version: &str) -> Result<(), sqlx::Error> {
        let removed: Option<i64> = on_pool!(&self.db, pool => {
            bind_key!(sqlx::query_scalar(DELETE_TILE), key, data_version)
                .fetch_optional(pool)
                .await?
        });
        if let Some(size) = removed {
            self.forget(size);
        }
        Ok(())
    }

    /// Deletes every stored tile (any scheme, encoding or version) and tile summary whose
    /// ground overlaps `area` and, on PostgreSQL, tells every replica in the same transaction (a replica hears of the
    /// change only once the tiles are gone); answers how many were deleted.
    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        let note = DataChangedNote {
            sender: self.replica.to_string(),
            area: *area,
        };
        let announce = self.dialect().announces_changes;
        let sizes: Vec<i64> = on_pool!(&self.db, pool => {
            let mut tx = pool.begin_write().await?;
            let sizes: Vec<i64> = sqlx::query_scalar(DELETE_OVERLAPPING)
                .bind(area.max_lon())
                .bind(area.min_lon())
                .bind(area.max_lat())
                .bind(area.min_lat())
                .fetch_all(&mut *tx)
                .await?;
            // The world tileset's summaries there were made from the old data too.
            sqlx::query(summaries::DELETE_OVERLAPPING_SUMMARIES)
                .bind(area.max_lon())
                .bind(area.min_lon())
                .bind(area.max_lat())
                .bind(area.min_lat())
                .execute(&mut *tx)
                .await?;
            if announce {
                sqlx::query("SELECT pg_notify($1, $2)")
                    .bind(DATA_CHANGED_CHANNEL)
                    .bind(note.payload())
                    .execute(&mut *tx)
                    .await?;
            }
            tx.commit().await?;
            sizes
        });
        sizes.iter().for_each(|&s| self.forget(s));
        Ok(sizes.len() as u64)
    }
}

/// The key's columns: scheme, region text, z, x, y.
pub(crate) fn columns(key: &TileKey) -> (&'static str, String, i64, i64, i64) {
    let scheme = key.tile.scheme();
    match key.tile {
        TileId::Xyz(t) | TileId::World(t) => (
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

//! The generated tiles on PostgreSQL (`--database-url`), shared by every replica: the same rows
//! and bound as the SQLite store, plus what many processes need: one generation per tile across
//! them (an advisory lock per key, see [`PgTileStore::turn`]) and a notification to every
//! replica when data changes (sent in the transaction that deletes the tiles over the area).

use super::{GenerationTurn, StoredTile, columns};
use crate::cache::key::TileKey;
use crate::clock::Clock;
use crate::db::UseNotes;
use bytes::Bytes;
use citymesh_core::geo::GeoBbox;
use sqlx::{PgPool, Postgres, Row, Transaction};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// The channel data changes are announced on (payload: [`DataChangedNote`]).
pub const DATA_CHANGED_CHANNEL: &str = "citymesh_data_changed";
/// What a row costs beyond its bytes, estimated (TOAST pages and the row header).
const ROW_OVERHEAD: i64 = 2_560;
/// Eviction goes down to this share of the bound.
const EVICT_TO: f64 = 0.8;
/// Tiles deleted per eviction statement.
const EVICT_BATCH: i64 = 32;
/// Uses noted before they are written.
const MAX_NOTED_USES: usize = 4_096;
/// Writes between two exact counts of the stored bytes (other replicas write too).
const RECOUNT_EVERY: u64 = 512;

/// A data change as announced to the replicas: who sent it and the area.
#[derive(Debug, Clone, PartialEq)]
pub struct DataChangedNote {
    pub sender: String,
    pub area: GeoBbox,
}

impl DataChangedNote {
    pub fn payload(&self) -> String {
        format!("{} {}", self.sender, self.area)
    }

    /// `None` for a payload that is not one (logged by the listener, never fatal).
    pub fn parse(payload: &str) -> Option<Self> {
        let (sender, area) = payload.split_once(' ')?;
        Some(Self {
            sender: sender.to_owned(),
            area: area.parse().ok()?,
        })
    }
}

/// The transaction holding a key's generation lock; committing (after the row is written)
/// releases it, and so does dropping it (rolled back).
pub struct PgGenerationLock(Transaction<'static, Postgres>);

#[derive(Clone)]
pub struct PgTileStore {
    pool: PgPool,
    max_bytes: u64,
    /// Who this replica is, in the notifications it sends.
    replica: Arc<str>,
    /// Bytes stored, as last counted plus this replica's writes since.
    used: Arc<AtomicU64>,
    writes: Arc<AtomicU64>,
    evicting: Arc<tokio::sync::Mutex<()>>,
    uses: Arc<UseNotes<(TileKey, String)>>,
    /// What writes and uses are stamped with.
    clock: Clock,
}

/// The condition that selects one key's row; [`bind_key`] binds $1 to $8.
macro_rules! key_where {
    () => {
        "scheme = $1 AND region = $2 AND z = $3 AND x = $4 AND y = $5 AND encoding = $6 \
         AND roofs = $7 AND data_version = $8"
    };
}

type Query<'q> = sqlx::query::Query<'q, Postgres, sqlx::postgres::PgArguments>;

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

/// The advisory lock's number for a key: the xxh3 of its columns (a collision only makes two
/// tiles wait for each other).
fn lock_id(key: &TileKey, data_version: &str) -> i64 {
    let (scheme, region, z, x, y) = columns(key);
    let text = format!(
        "{scheme}/{region}/{z}/{x}/{y}/{}/{}/{data_version}",
        key.encoding.as_str(),
        key.roofs.name()
    );
    xxhash_rust::xxh3::xxh3_64(text.as_bytes()) as i64
}

fn is_lock_timeout(e: &sqlx::Error) -> bool {
    matches!(e, sqlx::Error::Database(d) if d.code().as_deref() == Some("55P03"))
}

impl PgTileStore {
    /// The store with writes and uses stamped by `clock`.
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// A store bounded to `max_bytes` (`u64::MAX`: unbounded), announcing changes as `replica`.
    pub async fn bounded(pool: PgPool, max_bytes: u64, replica: &str) -> Result<Self, sqlx::Error> {
        let store = Self {
            pool,
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

    /// Counts the stored bytes exactly (every replica's).
    async fn recount(&self) -> Result<u64, sqlx::Error> {
        let used: i64 = sqlx::query("SELECT COALESCE(SUM(size), 0)::BIGINT FROM generated_tiles")
            .fetch_one(&self.pool)
            .await?
            .get(0);
        let used = u64::try_from(used).unwrap_or(0);
        self.used.store(used, Ordering::Relaxed);
        Ok(used)
    }

    /// Bytes of stored tiles, as last counted plus this replica's writes since.
    pub fn used_bytes(&self) -> u64 {
        self.used.load(Ordering::Relaxed)
    }

    /// The stored tile; its use is noted and written later (a read never writes).
    pub async fn get(
        &self,
        key: &TileKey,
        data_version: &str,
    ) -> Result<Option<StoredTile>, sqlx::Error> {
        let sql = concat!(
            "SELECT bytes, etag FROM generated_tiles WHERE ",
            key_where!()
        );
        let row = bind_key(sqlx::query(sql), key, data_version)
            .fetch_optional(&self.pool)
            .await?;
        if row.is_some()
            && self
                .uses
                .note((*key, data_version.to_owned()), self.clock.now_ms())
        {
            let store = self.clone();
            tokio::spawn(async move { store.write_uses().await });
        }
        Ok(row.map(stored_of_row))
    }

    /// Writes the noted uses in one transaction (best-effort, as on SQLite).
    pub async fn write_uses(&self) {
        let uses = self.uses.take();
        if uses.is_empty() {
            return;
        }
        let result = async {
            let mut tx = self.pool.begin().await?;
            for ((key, data_version), at) in &uses {
                let sql = concat!(
                    "UPDATE generated_tiles SET last_used = GREATEST(last_used, $9) WHERE ",
                    key_where!()
                );
                bind_key(sqlx::query(sql), key, data_version)
                    .bind(*at)
                    .execute(&mut *tx)
                    .await?;
            }
            tx.commit().await
        }
        .await;
        if let Err(e) = result {
            tracing::debug!(uses = uses.len(), "tile uses not written: {e}");
        }
    }

    /// Whose turn it is to generate a missing tile, across replicas. The first to ask takes the
    /// key's advisory lock and generates; the others wait for the lock (up to `wait`), then read
    /// the row the first wrote, or generate themselves if it has none (it failed, or its tile
    /// was outdated) or the wait ran out.
    pub async fn turn(
        &self,
        key: &TileKey,
        data_version: &str,
        wait: Duration,
    ) -> Result<GenerationTurn, sqlx::Error> {
        let id = lock_id(key, data_version);
        let mut tx = self.pool.begin().await?;
        let first: bool = sqlx::query("SELECT pg_try_advisory_xact_lock($1)")
            .bind(id)
            .fetch_one(&mut *tx)
            .await?
            .get(0);
        let mut waited = false;
        if !first {
            waited = true;
            // Whole milliseconds; PostgreSQL reads a bare number as milliseconds.
            let ms = wait.as_millis().clamp(1, 3_600_000).to_string();
            sqlx::query("SELECT set_config('lock_timeout', $1, true)")
                .bind(ms)
                .execute(&mut *tx)
                .await?;
            match sqlx::query("SELECT pg_advisory_xact_lock($1)")
                .bind(id)
                .execute(&mut *tx)
                .await
            {
                Ok(_) => {}
                Err(e) if is_lock_timeout(&e) => {
                    return Ok(GenerationTurn::Generate {
                        lock: None,
                        waited,
                        timed_out: true,
                    });
                }
                Err(e) => return Err(e),
            }
        }
        // Holding the lock: the row may have been written meanwhile (by the one who held it, or
        // just before this call took it).
        let sql = concat!(
            "SELECT bytes, etag FROM generated_tiles WHERE ",
            key_where!()
        );
        if let Some(row) = bind_key(sqlx::query(sql), key, data_version)
            .fetch_optional(&mut *tx)
            .await?
        {
            tx.commit().await?;
            return Ok(GenerationTurn::Stored {
                tile: stored_of_row(row),
                waited,
            });
        }
        Ok(GenerationTurn::Generate {
            lock: Some(super::GenerationLock::Postgres(PgGenerationLock(tx))),
            waited,
            timed_out: false,
        })
    }

    /// Stores a tile (replacing the key's row), inside the generation lock's transaction when
    /// held (committing it releases the waiting replicas), then evicts past the bound.
    pub async fn put(
        &self,
        key: &TileKey,
        data_version: &str,
        bytes: &[u8],
        etag: &str,
        lock: Option<PgGenerationLock>,
    ) -> Result<(), sqlx::Error> {
        let b = key.tile.bounds();
        let now = self.clock.now_ms();
        let cost = bytes.len() as i64 + ROW_OVERHEAD;
        // The replaced row's size (read before the insert, in the same statement) leaves the
        // count.
        let sql = concat!(
            "WITH old AS (SELECT size FROM generated_tiles WHERE ",
            key_where!(),
            ") INSERT INTO generated_tiles (scheme, region, z, x, y, encoding, roofs, \
             data_version, west, south, east, north, bytes, etag, created_at, size, last_used) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14, $15, $16, $17) \
             ON CONFLICT (scheme, region, z, x, y, encoding, roofs, data_version) DO UPDATE SET \
             bytes = EXCLUDED.bytes, etag = EXCLUDED.etag, created_at = EXCLUDED.created_at, \
             size = EXCLUDED.size, last_used = EXCLUDED.last_used \
             RETURNING (SELECT COALESCE(SUM(size), 0)::BIGINT FROM old)"
        );
        let query = bind_key(sqlx::query(sql), key, data_version)
            .bind(b.min_lon())
            .bind(b.min_lat())
            .bind(b.max_lon())
            .bind(b.max_lat())
            .bind(bytes.to_vec())
            .bind(etag.to_owned())
            .bind(now / 1000)
            .bind(cost)
            .bind(now);
        let replaced: i64 = match lock {
            Some(PgGenerationLock(mut tx)) => {
                let row = query.fetch_one(&mut *tx).await?;
                tx.commit().await?;
                row.get(0)
            }
            None => query.fetch_one(&self.pool).await?.get(0),
        };
        self.forget(replaced);
        self.used.fetch_add(cost as u64, Ordering::Relaxed);
        if self.writes.fetch_add(1, Ordering::Relaxed) % RECOUNT_EVERY == RECOUNT_EVERY - 1 {
            self.recount().await?;
        }
        self.evict_if_over().await
    }

    /// Past the bound (counted exactly first: other replicas evict too), deletes the least
    /// recently used tiles, 32 at a time, down to 80 % of it.
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        if self.used_bytes() <= self.max_bytes {
            return Ok(());
        }
        let _one = self.evicting.lock().await;
        let mut used = self.recount().await?;
        if used <= self.max_bytes {
            return Ok(());
        }
        self.write_uses().await;
        let target = (self.max_bytes as f64 * EVICT_TO) as u64;
        while used > target {
            let freed: Vec<i64> = sqlx::query(
                "DELETE FROM generated_tiles WHERE ctid IN (SELECT ctid FROM generated_tiles \
                 ORDER BY last_used LIMIT $1 FOR UPDATE SKIP LOCKED) RETURNING size",
            )
            .bind(EVICT_BATCH)
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
        self.used.store(used, Ordering::Relaxed);
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

    /// Deletes one key's row, if stored.
    pub async fn remove(&self, key: &TileKey, data_version: &str) -> Result<(), sqlx::Error> {
        let sql = concat!(
            "DELETE FROM generated_tiles WHERE ",
            key_where!(),
            " RETURNING size"
        );
        if let Some(row) = bind_key(sqlx::query(sql), key, data_version)
            .fetch_optional(&self.pool)
            .await?
        {
            self.forget(row.get(0));
        }
        Ok(())
    }

    /// Deletes every stored tile whose ground overlaps `area` and tells every replica, in one
    /// transaction (a replica hears of the change only once the tiles are gone); answers how
    /// many were deleted.
    pub async fn delete_overlapping(&self, area: &GeoBbox) -> Result<u64, sqlx::Error> {
        let mut tx = self.pool.begin().await?;
        let sizes: Vec<i64> = sqlx::query(
            "DELETE FROM generated_tiles WHERE west <= $1 AND east >= $2 AND south <= $3 \
             AND north >= $4 RETURNING size",
        )
        .bind(area.max_lon())
        .bind(area.min_lon())
        .bind(area.max_lat())
        .bind(area.min_lat())
        .fetch_all(&mut *tx)
        .await?
        .iter()
        .map(|r| r.get(0))
        .collect();
        let note = DataChangedNote {
            sender: self.replica.to_string(),
            area: *area,
        };
        sqlx::query("SELECT pg_notify($1, $2)")
            .bind(DATA_CHANGED_CHANNEL)
            .bind(note.payload())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        sizes.iter().for_each(|&s| self.forget(s));
        Ok(sizes.len() as u64)
    }
}

fn stored_of_row(row: sqlx::postgres::PgRow) -> StoredTile {
    StoredTile {
        bytes: Bytes::from(row.get::<Vec<u8>, _>(0)),
        etag: row.get(1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_note_reads_back_as_sent_and_garbage_is_none() {
        let note = DataChangedNote {
            sender: "r1".into(),
            area: "8.4,49,8.41,49.01".parse().unwrap(),
        };
        assert_eq!(DataChangedNote::parse(&note.payload()), Some(note));
        assert_eq!(DataChangedNote::parse("r1"), None);
        assert_eq!(DataChangedNote::parse("r1 not-a-box"), None);
    }
}

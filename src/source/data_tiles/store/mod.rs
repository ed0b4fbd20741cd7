//! OSM data tiles kept in the database (SQLite, or PostgreSQL shared by replicas) with their
//! fetch time, so the server can run offline and a restart does not ask upstream again. What came from Overpass is bounded in bytes
//! (`--osm-store-mb`): past the bound the least recently used data tiles are deleted (and
//! fetched again when needed); imported data is never evicted. Reads note their use in memory
//! and never write.

mod replication;
mod statements;

pub use replication::{ElementKind, ReplicationState};

use crate::clock::Clock;
use crate::db::{Database, UseNotes};
use bytes::Bytes;
use citymesh_core::geo::TileCoord;
use std::sync::Arc;

/// Where a stored data tile came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataOrigin {
    Overpass,
    Import,
}

impl DataOrigin {
    fn as_str(self) -> &'static str {
        match self {
            DataOrigin::Overpass => "overpass",
            DataOrigin::Import => "import",
        }
    }
}

/// A stored row as read.
fn stored_of(body: Bytes, hash: String, source: &str, fetched_at: i64) -> StoredDataTile {
    StoredDataTile {
        body,
        hash,
        origin: if source == "import" {
            DataOrigin::Import
        } else {
            DataOrigin::Overpass
        },
        fetched_at,
    }
}

/// One stored data tile.
#[derive(Debug, Clone)]
pub struct StoredDataTile {
    pub body: Bytes,
    pub hash: String,
    pub origin: DataOrigin,
    /// Unix seconds.
    pub fetched_at: i64,
}

#[derive(Clone)]
pub struct OsmTileStore {
    db: Database,
    /// Bytes of Overpass data at most (`u64::MAX`: unbounded).
    max_bytes: u64,
    /// Data tiles read since their uses were last written.
    uses: Arc<UseNotes<TileCoord>>,
    /// One eviction at a time.
    evicting: Arc<tokio::sync::Mutex<()>>,
    /// What fetch times and uses are stamped with.
    clock: Clock,
}

/// Uses noted before they are written with the next stored tile.
const MAX_NOTED_USES: usize = 4_096;

/// The content hash stored with a body.
pub fn content_hash(body: &[u8]) -> String {
    format!("{:016x}", xxhash_rust::xxh3::xxh3_64(body))
}

impl OsmTileStore {
    /// An unbounded store (for `citymesh import` and tests).
    pub fn new(db: Database) -> Self {
        Self::bounded(db, u64::MAX)
    }

    /// A store whose Overpass data is kept under `max_bytes`.
    pub fn bounded(db: Database, max_bytes: u64) -> Self {
        Self {
            db,
            max_bytes,
            uses: Arc::new(UseNotes::new(MAX_NOTED_USES)),
            evicting: Arc::new(tokio::sync::Mutex::new(())),
            clock: Clock::system(),
        }
    }

    /// The store with fetch times and uses stamped by `clock` (tests move a manual one).
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// The clock its rows are stamped with.
    pub fn clock(&self) -> &Clock {
        &self.clock
    }

    /// Bytes of stored Overpass data.
    pub async fn overpass_bytes(&self) -> Result<u64, sqlx::Error> {
        let used = statements::overpass_bytes(&self.db).await?;
        Ok(u64::try_from(used).unwrap_or(0))
    }

    /// Writes the noted uses, then deletes the least recently used Overpass data tiles, one at a
    /// time (each holds many buildings), while there are more bytes than the bound.
    async fn evict_if_over(&self) -> Result<(), sqlx::Error> {
        if self.max_bytes == u64::MAX {
            return Ok(());
        }
        let _one = self.evicting.lock().await;
        let uses = self.uses.take();
        if !uses.is_empty() {
            statements::write_uses(&self.db, &uses).await?;
        }
        let mut used = self.overpass_bytes().await?;
        while used > self.max_bytes {
            let sizes = statements::evict_least_used(&self.db).await?;
            if sizes.is_empty() {
                break;
            }
            let freed: i64 = sizes.iter().sum();
            used = used.saturating_sub(u64::try_from(freed).unwrap_or(0));
            tracing::debug!(
                evicted = sizes.len(),
                used,
                "OSM data store evicted data tiles"
            );
        }
        Ok(())
    }

    pub async fn get(&self, t: &TileCoord) -> Result<Option<StoredDataTile>, sqlx::Error> {
        let stored = statements::get(&self.db, t).await?;
        if stored.is_some() {
            // Written with the next stored tile; when many are noted, it is time.
            self.uses
                .note(*t, self.clock.now_secs().saturating_mul(1000));
        }
        Ok(stored)
    }

    /// Whether a data tile is stored (its body not read, its use not noted).
    pub async fn holds(&self, t: &TileCoord) -> Result<bool, sqlx::Error> {
        statements::holds(&self.db, t).await
    }

    /// Stores a data tile; answers whether its content changed (new, or a different body).
    pub async fn put(
        &self,
        t: &TileCoord,
        body: &[u8],
        origin: DataOrigin,
    ) -> Result<bool, sqlx::Error> {
        let hash = content_hash(body);
        let row = statements::NewRow {
            t,
            body,
            hash: &hash,
            origin,
            now_secs: self.clock.now_secs(),
        };
        let previous = statements::put(&self.db, &row).await?;
        if origin == DataOrigin::Overpass {
            self.evict_if_over().await?;
        }
        Ok(previous.as_deref() != Some(hash.as_str()))
    }

    /// A transaction that imports data tiles all at once: nothing is visible (or kept, if the
    /// import is interrupted) until [`ImportWriter::commit`].
    pub async fn import_writer(&self) -> Result<ImportWriter, sqlx::Error> {
        let tx = match &self.db {
            Database::Sqlite(p) => ImportTx::Sqlite(p.begin_with("BEGIN IMMEDIATE").await?),
            Database::Postgres(p) => ImportTx::Postgres(p.begin().await?),
        };
        Ok(ImportWriter {
            tx,
            clock: self.clock.clone(),
        })
    }

    /// Number of stored data tiles.
    pub async fn count(&self) -> Result<i64, sqlx::Error> {
        statements::count(&self.db).await
    }

    /// Every stored data tile (12 bytes of memory each: a country's are a few MB).
    pub async fn stored_tiles(&self) -> Result<Vec<TileCoord>, sqlx::Error> {
        statements::stored_tiles(&self.db).await
    }
}

/// Data tiles written in one transaction (see [`OsmTileStore::import_writer`]).
pub struct ImportWriter {
    tx: ImportTx,
    clock: Clock,
}

pub(super) enum ImportTx {
    Sqlite(sqlx::Transaction<'static, sqlx::Sqlite>),
    Postgres(sqlx::Transaction<'static, sqlx::Postgres>),
}

impl ImportWriter {
    /// Stores an imported data tile; answers whether its content changed.
    pub async fn put(&mut self, t: &TileCoord, body: &[u8]) -> Result<bool, sqlx::Error> {
        let changed = self.put_many(&[(*t, body)]).await?;
        Ok(changed.first().copied().unwrap_or(false))
    }

    /// Stores imported data tiles (distinct tiles) in one round trip where the database allows;
    /// answers, for each, whether its content changed.
    pub async fn put_many<B: AsRef<[u8]>>(
        &mut self,
        tiles: &[(TileCoord, B)],
    ) -> Result<Vec<bool>, sqlx::Error> {
        let now_secs = self.clock.now_secs();
        let hashes: Vec<String> = tiles
            .iter()
            .map(|(_, body)| content_hash(body.as_ref()))
            .collect();
        let rows: Vec<statements::NewRow<'_>> = tiles
            .iter()
            .zip(&hashes)
            .map(|((t, body), hash)| statements::NewRow {
                t,
                body: body.as_ref(),
                hash,
                origin: DataOrigin::Import,
                now_secs,
            })
            .collect();
        let previous = statements::put_many_in(&mut self.tx, &rows).await?;
        Ok(previous
            .iter()
            .zip(&hashes)
            .map(|(p, h)| p.as_deref() != Some(h.as_str()))
            .collect())
    }

    /// Makes every tile put visible at once.
    pub async fn commit(self) -> Result<(), sqlx::Error> {
        match self.tx {
            ImportTx::Sqlite(tx) => tx.commit().await,
            ImportTx::Postgres(tx) => tx.commit().await,
        }
    }
}

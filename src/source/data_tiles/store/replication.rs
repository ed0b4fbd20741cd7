//! What following replication diffs keeps beside the data tiles (tables of
//! `migrations/0015_replication.sql`): where the buildings made from each block of element ids
//! are stored, the last diff applied, and the areas whose generated content a diff made stale.
//! Each statement is written once for both backends.

use super::super::data_tile::DATA_ZOOM;
use super::{ImportTx, ImportWriter, OsmTileStore};
use crate::db::{BeginWrite as _, on_pool};
use citymesh_core::geo::{GeoBbox, TileCoord};
use sqlx::Row;

/// Element ids per row of `osm_element_tiles` (`id >> ID_BLOCK_BITS`).
pub const ID_BLOCK_BITS: u32 = 8;

/// The kinds of element the index knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ElementKind {
    Node = 0,
    Way = 1,
    Relation = 2,
}

/// The last diff applied.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplicationState {
    pub sequence: i64,
    /// As the feed's `state.txt` gives it (ISO 8601, UTC).
    pub timestamp: String,
    /// The feed (or the file applied by hand).
    pub url: String,
    /// Unix seconds.
    pub applied_at: i64,
}

/// Runs `$body` with `$conn` bound to the transaction's connection, whichever the backend.
macro_rules! on_tx {
    ($tx:expr, $conn:ident => $body:expr) => {
        match $tx {
            ImportTx::Sqlite(t) => {
                let $conn = &mut **t;
                $body
            }
            ImportTx::Postgres(t) => {
                let $conn = &mut **t;
                $body
            }
        }
    };
}

const INDEX_ROW: &str = "INSERT INTO osm_element_tiles (kind, block, x, y) VALUES ($1, $2, $3, \
    $4) ON CONFLICT DO NOTHING";
const SET_STATE: &str = "INSERT INTO osm_replication (id, sequence, timestamp, url, applied_at) \
    VALUES (1, $1, $2, $3, $4) ON CONFLICT (id) DO UPDATE SET sequence = excluded.sequence, \
    timestamp = excluded.timestamp, url = excluded.url, applied_at = excluded.applied_at";
const NOTE_AREA: &str =
    "INSERT INTO osm_changed_areas (west, south, east, north) VALUES ($1, $2, $3, $4)";

impl ImportWriter {
    /// Notes that `tile` holds buildings made from the elements `(kind, id)`.
    pub async fn index_elements(
        &mut self,
        tile: &TileCoord,
        elements: impl IntoIterator<Item = (ElementKind, i64)>,
    ) -> Result<(), sqlx::Error> {
        let mut blocks: Vec<(i64, i64)> = elements
            .into_iter()
            .map(|(k, id)| (k as i64, id >> ID_BLOCK_BITS))
            .collect();
        blocks.sort_unstable();
        blocks.dedup();
        on_tx!(&mut self.tx, conn => {
            for (kind, block) in blocks {
                sqlx::query(INDEX_ROW)
                    .bind(kind)
                    .bind(block)
                    .bind(i64::from(tile.x))
                    .bind(i64::from(tile.y))
                    .execute(&mut *conn)
                    .await?;
            }
        });
        Ok(())
    }

    /// Records the diff this transaction applies.
    pub async fn set_replication_state(
        &mut self,
        state: &ReplicationState,
    ) -> Result<(), sqlx::Error> {
        on_tx!(&mut self.tx, conn => {
            sqlx::query(SET_STATE)
                .bind(state.sequence)
                .bind(&state.timestamp)
                .bind(&state.url)
                .bind(state.applied_at)
                .execute(&mut *conn)
                .await?;
        });
        Ok(())
    }

    /// Notes areas whose generated content must be dropped once this transaction commits.
    pub async fn note_changed_areas(&mut self, areas: &[GeoBbox]) -> Result<(), sqlx::Error> {
        on_tx!(&mut self.tx, conn => {
            for a in areas {
                sqlx::query(NOTE_AREA)
                    .bind(a.min_lon())
                    .bind(a.min_lat())
                    .bind(a.max_lon())
                    .bind(a.max_lat())
                    .execute(&mut *conn)
                    .await?;
            }
        });
        Ok(())
    }

    /// The stored body of a data tile, read in this transaction.
    pub async fn get_body(&mut self, t: &TileCoord) -> Result<Option<Vec<u8>>, sqlx::Error> {
        let sql = "SELECT body FROM osm_data_tiles WHERE z = $1 AND x = $2 AND y = $3 \
                   AND source = 'import'";
        let body = on_tx!(&mut self.tx, conn => {
            sqlx::query_scalar(sql)
                .bind(i64::from(t.z))
                .bind(i64::from(t.x))
                .bind(i64::from(t.y))
                .fetch_optional(&mut *conn)
                .await?
        });
        Ok(body)
    }

    /// The data tiles holding buildings made from an element of the blocks of `ids`.
    pub async fn tiles_holding(
        &mut self,
        kind: ElementKind,
        ids: impl IntoIterator<Item = i64>,
    ) -> Result<Vec<TileCoord>, sqlx::Error> {
        let mut blocks: Vec<i64> = ids.into_iter().map(|id| id >> ID_BLOCK_BITS).collect();
        blocks.sort_unstable();
        blocks.dedup();
        let sql = "SELECT x, y FROM osm_element_tiles WHERE kind = $1 AND block = $2";
        let mut out = Vec::new();
        on_tx!(&mut self.tx, conn => {
            for block in blocks {
                let rows = sqlx::query(sql)
                    .bind(kind as i64)
                    .bind(block)
                    .fetch_all(&mut *conn)
                    .await?;
                for r in rows {
                    let (x, y): (i64, i64) = (r.get(0), r.get(1));
                    if let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y))
                        && let Ok(t) = TileCoord::new(u32::from(DATA_ZOOM), x, y)
                    {
                        out.push(t);
                    }
                }
            }
        });
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }

    /// The last diff applied, read in this transaction (PostgreSQL: the row locked, so two
    /// processes never apply the same diff).
    pub async fn replication_state(&mut self) -> Result<Option<ReplicationState>, sqlx::Error> {
        let row: Option<StateRow> = match &mut self.tx {
            ImportTx::Sqlite(t) => {
                sqlx::query_as(SELECT_STATE)
                    .fetch_optional(&mut **t)
                    .await?
            }
            ImportTx::Postgres(t) => {
                sqlx::query_as(SELECT_STATE_FOR_UPDATE)
                    .fetch_optional(&mut **t)
                    .await?
            }
        };
        Ok(row.map(state_of))
    }
}

const SELECT_STATE: &str =
    "SELECT sequence, timestamp, url, applied_at FROM osm_replication WHERE id = 1";

const SELECT_STATE_FOR_UPDATE: &str =
    "SELECT sequence, timestamp, url, applied_at FROM osm_replication WHERE id = 1 FOR UPDATE";

type StateRow = (i64, String, String, i64);

fn state_of((sequence, timestamp, url, applied_at): StateRow) -> ReplicationState {
    ReplicationState {
        sequence,
        timestamp,
        url,
        applied_at,
    }
}

impl OsmTileStore {
    /// The last diff applied, if any.
    pub async fn replication_state(&self) -> Result<Option<ReplicationState>, sqlx::Error> {
        let row: Option<StateRow> = on_pool!(&self.db, pool => {
            sqlx::query_as(SELECT_STATE).fetch_optional(pool).await?
        });
        Ok(row.map(state_of))
    }

    /// Whether the imported data can follow diffs: imported with the element index (an import
    /// by a citymesh before it has none).
    pub async fn is_indexed(&self) -> Result<bool, sqlx::Error> {
        let sql = "SELECT 1 FROM osm_element_tiles LIMIT 1";
        on_pool!(&self.db, pool => {
            Ok(sqlx::query(sql).fetch_optional(pool).await?.is_some())
        })
    }

    /// The areas noted stale and not yet dropped, with their row ids.
    pub async fn pending_areas(&self) -> Result<Vec<(i64, GeoBbox)>, sqlx::Error> {
        let sql = "SELECT id, west, south, east, north FROM osm_changed_areas ORDER BY id";
        let rows: Vec<(i64, f64, f64, f64, f64)> = on_pool!(&self.db, pool => {
            sqlx::query_as(sql).fetch_all(pool).await?
        });
        Ok(rows
            .into_iter()
            .filter_map(|(id, w, s, e, n)| Some((id, GeoBbox::new(w, s, e, n).ok()?)))
            .collect())
    }

    /// Forgets the areas whose content was dropped.
    pub async fn clear_areas(&self, ids: &[i64]) -> Result<(), sqlx::Error> {
        let sql = "DELETE FROM osm_changed_areas WHERE id = $1";
        on_pool!(&self.db, pool => {
            let mut tx = pool.begin_write().await?;
            for id in ids {
                sqlx::query(sql).bind(id).execute(&mut *tx).await?;
            }
            tx.commit().await?;
        });
        Ok(())
    }
}

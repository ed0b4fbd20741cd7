//! What the tile store does only on PostgreSQL, where many replicas share it: one generation
//! per tile across them (an advisory lock per key, see [`turn`]), and the announcement of a data
//! change (sent in the transaction that deletes the tiles over the area).

use super::{GenerationTurn, StoredTile, columns};
use crate::cache::key::TileKey;
use citymesh_core::geo::GeoBbox;
use sqlx::{PgPool, Postgres, Transaction};
use std::time::Duration;

/// The channel data changes are announced on (payload: [`DataChangedNote`]).
pub const DATA_CHANGED_CHANNEL: &str = "citymesh_data_changed";

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

/// A held right to generate a tile other replicas may also miss: the transaction holding the
/// key's advisory lock. Writing the tile with it commits it, releasing the replicas waiting;
/// dropping it (rolled back) releases them too.
pub struct GenerationLock(pub(super) Transaction<'static, Postgres>);

/// The advisory lock's number for a key: the xxh3 of its columns (a collision only makes two
/// tiles wait for each other).
fn lock_id(key: &TileKey, data_version: &str) -> i64 {
    let (scheme, region, z, x, y) = columns(key);
    let text = format!(
        "{scheme}/{region}/{z}/{x}/{y}/{}/{}/{data_version}",
        key.encoding.as_str(),
        key.content_name()
    );
    xxhash_rust::xxh3::xxh3_64(text.as_bytes()) as i64
}

fn is_lock_timeout(e: &sqlx::Error) -> bool {
    matches!(e, sqlx::Error::Database(d) if d.code().as_deref() == Some("55P03"))
}

/// Whose turn it is to generate a missing tile, across replicas. The first to ask takes the
/// key's advisory lock and generates; the others wait for the lock (up to `wait`), then read the
/// row the first wrote, or generate themselves if it has none (it failed, or its tile was
/// outdated) or the wait ran out.
pub(super) async fn turn(
    pool: &PgPool,
    key: &TileKey,
    data_version: &str,
    wait: Duration,
) -> Result<GenerationTurn, sqlx::Error> {
    let id = lock_id(key, data_version);
    let mut tx = pool.begin().await?;
    let first: bool = sqlx::query_scalar("SELECT pg_try_advisory_xact_lock($1)")
        .bind(id)
        .fetch_one(&mut *tx)
        .await?;
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
    let row: Option<(Vec<u8>, String)> =
        bind_key!(sqlx::query_as(super::SELECT_TILE), key, data_version)
            .fetch_optional(&mut *tx)
            .await?;
    if let Some(row) = row {
        tx.commit().await?;
        return Ok(GenerationTurn::Stored {
            tile: StoredTile::from(row),
            waited,
        });
    }
    Ok(GenerationTurn::Generate {
        lock: Some(GenerationLock(tx)),
        waited,
        timed_out: false,
    })
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

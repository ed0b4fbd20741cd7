//! The world tileset's tile summaries kept in the tile store's database (table
//! `tile_summaries`), so a restart reads them instead of making them again from every data
//! tile: one row per tile, stamped with the data version it was made for. They are dropped with
//! the generated tiles over any area whose data changes ([`TileStore::delete_overlapping`]), and
//! not counted in the store's byte bound (there is one per tile with data, a few kB each).

use super::TileStore;
use crate::db::{BeginWrite as _, on_pool};
use citymesh_core::geo::TileCoord;
use citymesh_core::tiles3d::TileSummary;

const SELECT_SUMMARY: &str =
    "SELECT bytes FROM tile_summaries WHERE z = $1 AND x = $2 AND y = $3 AND data_version = $4";
const UPSERT_SUMMARY: &str = "INSERT INTO tile_summaries (z, x, y, data_version, west, south, \
    east, north, bytes) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) ON CONFLICT (z, x, y) DO \
    UPDATE SET data_version = excluded.data_version, west = excluded.west, \
    south = excluded.south, east = excluded.east, north = excluded.north, bytes = excluded.bytes";
const DELETE_SUMMARY: &str = "DELETE FROM tile_summaries WHERE z = $1 AND x = $2 AND y = $3";
/// Summaries over an area (`$1` to `$4` as for the generated tiles).
pub(super) const DELETE_OVERLAPPING_SUMMARIES: &str = "DELETE FROM tile_summaries WHERE \
    west <= $1 AND east >= $2 AND south <= $3 AND north >= $4";

/// Summaries written in one transaction at most.
const WRITE_BATCH: usize = 256;

impl TileStore {
    /// The kept summary of `tile` made for `data_version`; `None` when there is none, or when
    /// the row cannot be read as a summary (it is made again, and replaces the row).
    pub async fn summary(
        &self,
        tile: TileCoord,
        data_version: &str,
    ) -> Result<Option<TileSummary>, sqlx::Error> {
        let bytes: Option<Vec<u8>> = on_pool!(&self.db, pool => {
            sqlx::query_scalar(SELECT_SUMMARY)
                .bind(i64::from(tile.z))
                .bind(i64::from(tile.x))
                .bind(i64::from(tile.y))
                .bind(data_version)
                .fetch_optional(pool)
                .await?
        });
        Ok(bytes.and_then(|b| match TileSummary::from_bytes(&b) {
            Ok(s) if s.tile == tile => Some(s),
            Ok(s) => {
                tracing::warn!(?tile, kept = ?s.tile, "a kept summary names another tile; made again");
                None
            }
            Err(e) => {
                tracing::warn!(?tile, "a kept summary cannot be read ({e}); made again");
                None
            }
        }))
    }

    /// Keeps `summaries` (`None`: the tile has no summary any more, its row goes), in
    /// transactions of at most [`WRITE_BATCH`].
    pub async fn put_summaries(
        &self,
        summaries: &[(TileCoord, Option<&TileSummary>)],
        data_version: &str,
    ) -> Result<(), sqlx::Error> {
        for batch in summaries.chunks(WRITE_BATCH) {
            on_pool!(&self.db, pool => {
                let mut tx = pool.begin_write().await?;
                for (t, summary) in batch {
                    let (z, x, y) = (i64::from(t.z), i64::from(t.x), i64::from(t.y));
                    match summary {
                        Some(s) => {
                            let b = t.bounds();
                            sqlx::query(UPSERT_SUMMARY)
                                .bind(z)
                                .bind(x)
                                .bind(y)
                                .bind(data_version)
                                .bind(b.min_lon())
                                .bind(b.min_lat())
                                .bind(b.max_lon())
                                .bind(b.max_lat())
                                .bind(s.to_bytes())
                                .execute(&mut *tx)
                                .await?;
                        }
                        None => {
                            sqlx::query(DELETE_SUMMARY)
                                .bind(z)
                                .bind(x)
                                .bind(y)
                                .execute(&mut *tx)
                                .await?;
                        }
                    }
                }
                tx.commit().await?;
            });
        }
        Ok(())
    }
}

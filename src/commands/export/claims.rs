//! The units of an export in the database, claimed under a lease as roof jobs are (SQLite on one
//! machine, PostgreSQL shared by exporters on many): a unit is claimed by one exporter at a
//! time, kept by extending its lease while it works, and taken over by another once the lease
//! runs out (its exporter died). A unit done stores its summary (3D Tiles), which the unit
//! above it reads; a unit waits until every unit below it is done.

use super::plan::Unit;
use crate::clock::Clock;
use crate::db::{BeginWrite as _, Database, on_pool};
use citymesh_core::geo::TileCoord;
use sqlx::Row;
use std::time::Duration;

/// Units inserted per statement when an export is planned.
const SEED_CHUNK: usize = 200;

/// A unit this exporter holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Claimed {
    pub id: i64,
    pub tile: TileCoord,
    pub claim: i64,
    /// Another claim held it before (an exporter died holding it, or gave it back).
    pub again: bool,
}

/// How far the export as a whole is, over every exporter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Progress {
    /// Files of the units done.
    pub files_done: u64,
    /// Files of the units done, and at most those of the units not done yet.
    pub files_total: u64,
    pub units_done: u64,
    pub units: u64,
}

/// One export's units on the database.
#[derive(Clone)]
pub struct Claims {
    db: Database,
    export: String,
    clock: Clock,
}

const INSERT_EXPORT: &str = "INSERT INTO exports (export, describe, units, created_at) \
    VALUES ($1, $2, $3, $4) ON CONFLICT DO NOTHING";

const EXPORT_UNITS: &str = "SELECT units FROM exports WHERE export = $1";

const SQLITE_CLAIM: &str = "UPDATE export_units SET state = 'running', claim = $1, \
    lease_until = $2, attempts = attempts + 1 WHERE export = $3 AND id = (SELECT u.id FROM export_units u \
    WHERE u.export = $3 AND (u.state = 'pending' OR (u.state = 'running' AND u.lease_until < $4)) \
    AND NOT EXISTS (SELECT 1 FROM export_units c WHERE c.export = $3 AND c.parent = u.id \
    AND c.state <> 'done') ORDER BY u.id LIMIT 1) RETURNING id, z, x, y, attempts";

/// PostgreSQL picks with `SKIP LOCKED`: two exporters never take the same unit, and neither
/// waits for the other.
const POSTGRES_CLAIM: &str = "WITH picked AS (SELECT u.id FROM export_units u \
    WHERE u.export = $3 AND (u.state = 'pending' OR (u.state = 'running' AND u.lease_until < $4)) \
    AND NOT EXISTS (SELECT 1 FROM export_units c WHERE c.export = $3 AND c.parent = u.id \
    AND c.state <> 'done') ORDER BY u.id LIMIT 1 FOR UPDATE OF u SKIP LOCKED) \
    UPDATE export_units e SET state = 'running', claim = $1, lease_until = $2, \
    attempts = e.attempts + 1 FROM picked WHERE e.export = $3 AND e.id = picked.id \
    RETURNING e.id, e.z, e.x, e.y, e.attempts";

const EXTEND: &str = "UPDATE export_units SET lease_until = $1 WHERE export = $2 AND id = $3 \
    AND claim = $4 AND state = 'running'";

const DONE: &str = "UPDATE export_units SET state = 'done', lease_until = NULL, files = $1, \
    summary = $2 WHERE export = $3 AND id = $4 AND claim = $5 AND state = 'running'";

const RELEASE: &str = "UPDATE export_units SET state = 'pending', lease_until = NULL, \
    claim = NULL WHERE export = $1 AND id = $2 AND claim = $3 AND state = 'running'";

const RESET: &str = "UPDATE export_units SET state = 'pending', lease_until = NULL, \
    claim = NULL, files = NULL, summary = NULL WHERE export = $1 AND id = $2";

/// Sums cast to BIGINT: PostgreSQL sums BIGINT as NUMERIC.
const PROGRESS: &str = "SELECT \
    CAST(COALESCE(SUM(CASE WHEN state = 'done' THEN files ELSE 0 END), 0) AS BIGINT), \
    CAST(COALESCE(SUM(CASE WHEN state = 'done' THEN files ELSE files_est END), 0) AS BIGINT), \
    CAST(COALESCE(SUM(CASE WHEN state = 'done' THEN 1 ELSE 0 END), 0) AS BIGINT), COUNT(*) \
    FROM export_units WHERE export = $1";

const CHILDREN: &str = "SELECT z, x, y, summary FROM export_units WHERE export = $1 \
    AND parent = $2 AND state = 'done' ORDER BY id";

const DONE_UNITS: &str = "SELECT id, z, x, y, files FROM export_units \
    WHERE export = $1 AND state = 'done' ORDER BY id";

/// A unit done, as [`Claims::done_units`] lists it.
#[derive(Debug, Clone, Copy)]
pub struct DoneUnit {
    pub id: i64,
    pub tile: TileCoord,
    pub files: i64,
}

fn tile_of(row: &impl RowLike) -> Result<TileCoord, sqlx::Error> {
    let (z, x, y) = (row.int(1)?, row.int(2)?, row.int(3)?);
    TileCoord::new(
        u32::try_from(z).unwrap_or(u32::MAX),
        u32::try_from(x).unwrap_or(u32::MAX),
        u32::try_from(y).unwrap_or(u32::MAX),
    )
    .map_err(|e| sqlx::Error::Decode(format!("an export unit's tile: {e}").into()))
}

/// The integer columns of a row of either backend.
trait RowLike {
    fn int(&self, i: usize) -> Result<i64, sqlx::Error>;
}

impl RowLike for sqlx::sqlite::SqliteRow {
    fn int(&self, i: usize) -> Result<i64, sqlx::Error> {
        self.try_get(i)
    }
}

impl RowLike for sqlx::postgres::PgRow {
    fn int(&self, i: usize) -> Result<i64, sqlx::Error> {
        self.try_get(i)
    }
}

impl Claims {
    /// The database the claims (and the exported data) are in.
    pub(super) fn database(&self) -> &Database {
        &self.db
    }

    /// The units of export `export` (`describe` says what it writes, for a person reading the
    /// table), planned as `units` if no exporter planned them yet: every exporter of the same
    /// export plans the same units, and the first to commit writes them.
    pub async fn open(
        db: &Database,
        export: &str,
        describe: &str,
        units: &[Unit],
        clock: Clock,
    ) -> anyhow::Result<Self> {
        let now = clock.now_ms();
        let count = units.len() as i64;
        let planned: i64 = on_pool!(db, pool => {
            let mut tx = pool.begin_write().await?;
            let new = sqlx::query(INSERT_EXPORT)
                .bind(export)
                .bind(describe)
                .bind(count)
                .bind(now)
                .execute(&mut *tx)
                .await?
                .rows_affected()
                == 1;
            if new {
                for chunk in units.chunks(SEED_CHUNK) {
                    let mut sql = String::from(
                        "INSERT INTO export_units (export, id, z, x, y, parent, files_est) VALUES ",
                    );
                    for i in 0..chunk.len() {
                        let b = i * 7;
                        if i > 0 {
                            sql.push(',');
                        }
                        sql.push_str(&format!(
                            "(${}, ${}, ${}, ${}, ${}, ${}, ${})",
                            b + 1, b + 2, b + 3, b + 4, b + 5, b + 6, b + 7
                        ));
                    }
                    // Only placeholders are formatted in: every value is bound.
                    let mut q = sqlx::query(sqlx::AssertSqlSafe(sql));
                    for u in chunk {
                        q = q
                            .bind(export)
                            .bind(u.id)
                            .bind(i64::from(u.tile.z))
                            .bind(i64::from(u.tile.x))
                            .bind(i64::from(u.tile.y))
                            .bind(u.parent)
                            .bind(u.files_est);
                    }
                    q.execute(&mut *tx).await?;
                }
            }
            let planned: i64 = sqlx::query_scalar(EXPORT_UNITS)
                .bind(export)
                .fetch_one(&mut *tx)
                .await?;
            tx.commit().await?;
            planned
        });
        anyhow::ensure!(
            planned == count,
            "export {export} was planned with {planned} units and is {count} now: the data \
             changed under the same data version; remove its rows (DELETE FROM export_units \
             WHERE export = '{export}') to start it again"
        );
        Ok(Self {
            db: db.clone(),
            export: export.to_owned(),
            clock,
        })
    }

    /// Claims the first unit that is free (pending, or running with a lease run out) and whose
    /// units below are all done, for `lease`.
    pub async fn claim(&self, lease: Duration) -> Result<Option<Claimed>, sqlx::Error> {
        let now = self.clock.now_ms();
        let claim = random_claim();
        let until = lease_end(now, lease);
        let claimed = match &self.db {
            Database::Sqlite(pool) => {
                let row = sqlx::query(SQLITE_CLAIM)
                    .bind(claim)
                    .bind(until)
                    .bind(&self.export)
                    .bind(now)
                    .fetch_optional(pool)
                    .await?;
                row.map(|r| Ok::<_, sqlx::Error>((r.int(0)?, tile_of(&r)?, r.int(4)?)))
                    .transpose()?
            }
            Database::Postgres(pool) => {
                let row = sqlx::query(POSTGRES_CLAIM)
                    .bind(claim)
                    .bind(until)
                    .bind(&self.export)
                    .bind(now)
                    .fetch_optional(pool)
                    .await?;
                row.map(|r| Ok::<_, sqlx::Error>((r.int(0)?, tile_of(&r)?, r.int(4)?)))
                    .transpose()?
            }
        };
        Ok(claimed.map(|(id, tile, attempts)| Claimed {
            id,
            tile,
            claim,
            again: attempts > 1,
        }))
    }

    /// Extends the lease of a unit still held; `false` when another exporter took it over.
    pub async fn extend(&self, unit: &Claimed, lease: Duration) -> Result<bool, sqlx::Error> {
        let until = lease_end(self.clock.now_ms(), lease);
        Ok(on_pool!(&self.db, pool => {
            sqlx::query(EXTEND)
                .bind(until)
                .bind(&self.export)
                .bind(unit.id)
                .bind(unit.claim)
                .execute(pool)
                .await?
                .rows_affected()
                == 1
        }))
    }

    /// Marks a unit held done, with the files it has and its summary.
    pub async fn done(
        &self,
        unit: &Claimed,
        files: i64,
        summary: Option<Vec<u8>>,
    ) -> Result<bool, sqlx::Error> {
        Ok(on_pool!(&self.db, pool => {
            sqlx::query(DONE)
                .bind(files)
                .bind(summary)
                .bind(&self.export)
                .bind(unit.id)
                .bind(unit.claim)
                .execute(pool)
                .await?
                .rows_affected()
                == 1
        }))
    }

    /// Gives a unit held back (this exporter stops on an error): another, or a rerun, takes it
    /// at once instead of after its lease.
    pub async fn release(&self, unit: &Claimed) -> Result<(), sqlx::Error> {
        on_pool!(&self.db, pool => {
            sqlx::query(RELEASE)
                .bind(&self.export)
                .bind(unit.id)
                .bind(unit.claim)
                .execute(pool)
                .await?;
        });
        Ok(())
    }

    /// Makes a unit done to do again (its files are not all there).
    pub async fn reset(&self, id: i64) -> Result<(), sqlx::Error> {
        on_pool!(&self.db, pool => {
            sqlx::query(RESET).bind(&self.export).bind(id).execute(pool).await?;
        });
        Ok(())
    }

    pub async fn progress(&self) -> Result<Progress, sqlx::Error> {
        let (a, b, c, d): (i64, i64, i64, i64) = on_pool!(&self.db, pool => {
            sqlx::query_as(PROGRESS).bind(&self.export).fetch_one(pool).await?
        });
        let u = |v: i64| u64::try_from(v).unwrap_or(0);
        Ok(Progress {
            files_done: u(a),
            files_total: u(b),
            units_done: u(c),
            units: u(d),
        })
    }

    /// The summaries the done units below unit `id` stored (`None`: the unit's tile holds no
    /// group).
    pub async fn children(
        &self,
        id: i64,
    ) -> Result<Vec<(TileCoord, Option<Vec<u8>>)>, sqlx::Error> {
        on_pool!(&self.db, pool => {
            sqlx::query(CHILDREN)
                .bind(&self.export)
                .bind(id)
                .fetch_all(pool)
                .await?
                .iter()
                .map(|r| {
                    // The tile's columns are 0 to 2 here.
                    let tile = TileCoord::new(
                        u32::try_from(r.try_get::<i64, _>(0)?).unwrap_or(u32::MAX),
                        u32::try_from(r.try_get::<i64, _>(1)?).unwrap_or(u32::MAX),
                        u32::try_from(r.try_get::<i64, _>(2)?).unwrap_or(u32::MAX),
                    )
                    .map_err(|e| sqlx::Error::Decode(format!("an export unit's tile: {e}").into()))?;
                    Ok((tile, r.try_get::<Option<Vec<u8>>, _>(3)?))
                })
                .collect()
        })
    }

    /// Every unit done.
    pub async fn done_units(&self) -> Result<Vec<DoneUnit>, sqlx::Error> {
        on_pool!(&self.db, pool => {
            sqlx::query(DONE_UNITS)
                .bind(&self.export)
                .fetch_all(pool)
                .await?
                .iter()
                .map(|r| {
                    Ok(DoneUnit {
                        id: r.int(0)?,
                        tile: tile_of(r)?,
                        files: r.try_get::<Option<i64>, _>(4)?.unwrap_or(0),
                    })
                })
                .collect()
        })
    }
}

fn lease_end(now: i64, lease: Duration) -> i64 {
    now.saturating_add(i64::try_from(lease.as_millis()).unwrap_or(i64::MAX))
}

/// A random claim number (a unit's holder proves itself with it).
fn random_claim() -> i64 {
    let mut bytes = [0u8; 8];
    // Without randomness, the time and the process: still distinct between exporters.
    if getrandom::fill(&mut bytes).is_err() {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        return (now ^ (u64::from(std::process::id()) << 40)) as i64;
    }
    i64::from_le_bytes(bytes)
}

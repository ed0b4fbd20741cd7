//! PostgreSQL (`--database-url postgres://...`): a pool through sqlx's pure-Rust driver, with the
//! migrations of `migrations/postgres/` applied at start-up (under sqlx's advisory lock, so
//! replicas starting together apply them once).

use sqlx::PgPool;
use sqlx::postgres::PgPoolOptions;

/// Connects to `url` and applies the migrations.
pub async fn open_postgres(url: &str, max_connections: u32) -> anyhow::Result<PgPool> {
    let pool = PgPoolOptions::new()
        .max_connections(max_connections)
        .acquire_timeout(super::BUSY_TIMEOUT)
        .connect(url)
        .await
        .map_err(|e| {
            anyhow::anyhow!(
                "cannot connect to PostgreSQL ({e}): check that the server runs, that the URL's \
                 host, port, user, password and database are right, and that it accepts this host"
            )
        })?;
    sqlx::migrate!("./migrations/postgres").run(&pool).await?;
    Ok(pool)
}

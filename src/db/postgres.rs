//! PostgreSQL (`--database-url postgres://...`, work in progress): a pool through sqlx's
//! pure-Rust driver, with the migrations of `migrations/postgres/` applied at start-up.

use sqlx::PgPool;
use sqlx::postgres::PgPoolOptions;

/// Connects to `url` and applies the migrations.
pub async fn open_postgres(url: &str, max_connections: u32) -> anyhow::Result<PgPool> {
    let pool = PgPoolOptions::new()
        .max_connections(max_connections)
        .acquire_timeout(std::time::Duration::from_secs(5))
        .connect(url)
        .await
        .map_err(|e| anyhow::anyhow!("cannot connect to the database {url}: {e}"))?;
    sqlx::migrate!("./migrations/postgres").run(&pool).await?;
    Ok(pool)
}

//! The database options every command that keeps state shares: the SQLite file on one machine,
//! or a PostgreSQL server shared by replicas.

use crate::db::Database;
use anyhow::Context;
use clap::Args;

/// Where citymesh keeps data tiles, generated tiles, roof jobs, predictions and imagery.
#[derive(Debug, Clone, Args)]
pub struct DatabaseArgs {
    /// SQLite file for cached data, generated tiles and roof jobs (created if missing;
    /// `:memory:` for none). Ignored with --database-url.
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// PostgreSQL to keep everything in instead of the SQLite file, shared by every replica
    /// (`postgres://user:password@host:5432/citymesh`). Its migrations run at start-up.
    #[arg(long, env = "CITYMESH_DATABASE_URL")]
    pub database_url: Option<String>,

    /// Connections to PostgreSQL this process opens at most (each generation a replica waits
    /// for, and each running one, holds one).
    #[arg(long, env = "CITYMESH_DATABASE_MAX_CONNECTIONS", default_value_t = 16)]
    pub database_max_connections: u32,
}

impl DatabaseArgs {
    /// Opens the database these options name, migrations applied.
    pub async fn open(&self) -> anyhow::Result<Database> {
        Database::open(
            self.database_url.as_deref(),
            &self.cache_db,
            self.database_max_connections.max(2),
        )
        .await
        .with_context(|| format!("opening the database {}", self.describe()))
    }

    /// The database, named without its password.
    pub fn describe(&self) -> String {
        match &self.database_url {
            Some(url) => match reqwest::Url::parse(url) {
                Ok(mut u) => {
                    if u.password().is_some() {
                        let _ = u.set_password(Some("***"));
                    }
                    u.to_string()
                }
                Err(_) => "(a --database-url that is not a URL)".to_owned(),
            },
            None => self.cache_db.clone(),
        }
    }
}

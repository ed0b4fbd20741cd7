//! Options of `citymesh replicate`: follow an OpenStreetMap replication feed.

use clap::Parser;

/// Options of `citymesh replicate`.
#[derive(Debug, Clone, Parser)]
pub struct ReplicateArgs {
    /// The feed's base URL: the folder holding `state.txt` and `AAA/BBB/CCC.osc.gz`
    /// (`https://planet.openstreetmap.org/replication/minute`, or a Geofabrik region's
    /// `...-updates`).
    #[arg(long)]
    pub url: String,

    /// The first sequence to apply when the store has applied none yet: the first one after
    /// the imported data's time (later runs go on from the stored one).
    #[arg(long)]
    pub from_sequence: Option<i64>,

    /// Apply what the feed has now and stop (exit status 1 on an error), instead of following
    /// it.
    #[arg(long)]
    pub once: bool,

    /// Seconds between checks of the feed when caught up.
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    pub interval_s: u64,

    /// The longest wait, in seconds, after errors (the first retry waits 1 s, doubling).
    #[arg(long, default_value_t = 600, value_parser = clap::value_parser!(u64).range(1..))]
    pub max_backoff_s: u64,

    /// The database the data was imported into.
    #[command(flatten)]
    pub database: super::DatabaseArgs,
}

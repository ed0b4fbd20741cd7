//! `citymesh replicate --url BASE` and `citymesh import --changes FILE`: OpenStreetMap change
//! files applied to the imported data (`crate::source::data_tiles::replication`), the
//! generated tiles over what changed dropped (`crate::cache`). As for an import, a server on
//! SQLite keeps what it parsed in memory: run `serve --replicate-url` to follow a feed inside
//! the server, or restart it; replicas on PostgreSQL hear of every change.

use crate::cache::TileStore;
use crate::cli::ReplicateArgs;
use crate::db::Database;
use crate::source::data_tiles::OsmTileStore;
use crate::source::data_tiles::replication::apply::{DiffReport, apply_change};
use crate::source::data_tiles::replication::feed::{
    Feed, FollowTiming, catch_up, follow, read_change_file,
};
use anyhow::Context;
use std::path::Path;
use std::time::Duration;

/// The report line of one diff.
pub fn describe(r: &DiffReport) -> String {
    format!(
        "{}{} elements, {} buildings changed ({} outside the imported extent), {} data tiles \
         written, {} generated tiles dropped, {:.2} s",
        r.sequence
            .map(|s| format!("sequence {s}: "))
            .unwrap_or_default(),
        r.elements,
        r.buildings_changed,
        r.outside_extent,
        r.data_tiles_written,
        r.tiles_dropped,
        r.seconds
    )
}

/// Applies one change file by hand.
pub async fn apply_file(path: &Path, db: &Database) -> anyhow::Result<DiffReport> {
    let name = path.display().to_string();
    let bytes = crate::source::read_osm_file(path)?;
    let change = read_change_file(&bytes).with_context(|| format!("{name}: an osmChange file"))?;
    let store = OsmTileStore::new(db.clone());
    let tiles = TileStore::open(db, u64::MAX, "replicate").await?;
    let report = apply_change(&store, &tiles, change, None)
        .await
        .with_context(|| format!("{name}: not applied, the store is as it was"))?;
    Ok(report.unwrap_or_default())
}

/// `citymesh replicate`.
pub async fn run(args: ReplicateArgs) -> anyhow::Result<()> {
    let db = args.database.open().await?;
    let store = OsmTileStore::new(db.clone());
    let tiles = TileStore::open(&db, u64::MAX, "replicate").await?;
    let feed = Feed::new(&args.url)?;
    if args.once {
        let reports = catch_up(&store, &tiles, &feed, args.from_sequence, |r| {
            println!("{}", describe(r));
        })
        .await?;
        let state = store.replication_state().await?;
        println!(
            "{} diffs applied; the data is at {}",
            reports.len(),
            state.map_or("no sequence yet".to_owned(), |s| format!(
                "sequence {} ({})",
                s.sequence, s.timestamp
            ))
        );
        return Ok(());
    }
    let timing = FollowTiming {
        interval: Duration::from_secs(args.interval_s),
        max_backoff: Duration::from_secs(args.max_backoff_s),
    };
    follow(
        store,
        tiles,
        feed,
        args.from_sequence,
        timing,
        |r| println!("{}", describe(r)),
        |e| eprintln!("replication: {e} (retrying)"),
    )
    .await;
    Ok(())
}

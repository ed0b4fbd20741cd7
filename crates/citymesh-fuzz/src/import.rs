//! `citymesh import` on hostile files: whatever the bytes (a way reaching across the world, a
//! node id given twice, truncated or mutated data), the import answers, and writes either the
//! whole file's data tiles or none, and never more data tiles than the bound on one building's
//! extent allows for the buildings it kept.

use citymesh::db::{self, Database};
use citymesh::source::data_tiles::OsmTileStore;
use std::sync::OnceLock;

/// Data tiles one building of at most 2 km may touch: zoom 14 tiles are 2.4 km wide at the
/// equator but 211 m where Web Mercator ends (85.05 degrees), so up to 11 by 11 there (a part
/// counts as a building).
const MAX_TILES_PER_BUILDING: usize = 144;

fn runtime() -> Option<&'static tokio::runtime::Runtime> {
    static RUNTIME: OnceLock<Option<tokio::runtime::Runtime>> = OnceLock::new();
    RUNTIME
        .get_or_init(|| {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .ok()
        })
        .as_ref()
}

/// Imports the bytes as a file into a fresh in-memory store.
pub fn import(bytes: &[u8]) {
    let Some(runtime) = runtime() else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("citymesh-fuzz-import-{}", std::process::id()));
    if std::fs::create_dir_all(&dir).is_err() {
        return;
    }
    let file = dir.join("input.osm");
    if std::fs::write(&file, bytes).is_err() {
        return;
    }
    runtime.block_on(async {
        let Ok(pool) = db::open(":memory:").await else {
            return;
        };
        let db = Database::Sqlite(pool);
        let result =
            citymesh::commands::import::import_into(std::slice::from_ref(&file), &db, true).await;
        let stored = OsmTileStore::new(db.clone()).count().await.unwrap_or(0);
        match result {
            Ok(report) => {
                assert_eq!(
                    stored as usize, report.data_tiles,
                    "a report that is not the store"
                );
                assert!(
                    report.data_tiles <= report.buildings.max(1) * MAX_TILES_PER_BUILDING,
                    "{} buildings wrote {} data tiles",
                    report.buildings,
                    report.data_tiles
                );
            }
            Err(e) => assert_eq!(stored, 0, "a failed import ({e}) left {stored} data tiles"),
        }
    });
}

//! The store of generated tiles on SQLite and on PostgreSQL (work in progress, issue 27): one
//! scenario, two backends, the same answers.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use citymesh::cache::{PgTileStore, StoredTile, TileKey, TileStore};
use citymesh_core::geo::TileCoord;

enum Store {
    Sqlite(TileStore),
    Pg(PgTileStore),
}

impl Store {
    async fn get(&self, key: &TileKey, v: &str) -> Option<StoredTile> {
        match self {
            Store::Sqlite(s) => s.get(key, v).await.unwrap(),
            Store::Pg(s) => s.get(key, v).await.unwrap(),
        }
    }
    async fn put(&self, key: &TileKey, v: &str, bytes: &[u8], etag: &str) {
        match self {
            Store::Sqlite(s) => s.put(key, v, bytes, etag).await.unwrap(),
            Store::Pg(s) => s.put(key, v, bytes, etag).await.unwrap(),
        }
    }
    async fn delete_overlapping(&self, area: &citymesh_core::geo::GeoBbox) -> u64 {
        match self {
            Store::Sqlite(s) => s.delete_overlapping(area).await.unwrap(),
            Store::Pg(s) => s.delete_overlapping(area).await.unwrap(),
        }
    }
    async fn used(&self) -> u64 {
        match self {
            Store::Sqlite(s) => s.used_bytes(),
            Store::Pg(s) => s.used_bytes().await.unwrap(),
        }
    }
}

/// Tile cost on both backends: bytes and the estimated row overhead.
const COST: u64 = 1_000 + 2_560;

fn key(i: u32) -> TileKey {
    TileKey::xyz(TileCoord::new(16, 34_290 + i, 22_493).unwrap())
}

async fn scenario(store: Store) -> Vec<String> {
    let mut seen = Vec::new();
    store.put(&key(0), "v1", &[1; 1_000], "a").await;
    let got = store.get(&key(0), "v1").await.unwrap();
    seen.push(format!("{} {} {}", got.bytes.len(), got.bytes[0], got.etag));
    seen.push(format!("{}", store.get(&key(0), "v2").await.is_none()));
    store.put(&key(0), "v1", &[2; 1_000], "b").await;
    let got = store.get(&key(0), "v1").await.unwrap();
    seen.push(format!(
        "{} {} {}",
        got.bytes[0],
        got.etag,
        store.used().await == COST
    ));
    let area = key(0).tile.bounds();
    seen.push(format!("{}", store.delete_overlapping(&area).await));
    seen.push(format!("{}", store.get(&key(0), "v1").await.is_none()));
    // Past the bound of 40 tiles, the least recently used go first, 32 at a time: 1 and 2 were
    // read again, so 3 to 34 go.
    let tick = || tokio::time::sleep(std::time::Duration::from_millis(2));
    for i in 1..=40 {
        store.put(&key(i), "v1", &[3; 1_000], "c").await;
        tick().await;
    }
    store.get(&key(1), "v1").await.unwrap();
    tick().await;
    store.get(&key(2), "v1").await.unwrap();
    tick().await;
    store.put(&key(41), "v1", &[4; 1_000], "d").await;
    let mut kept = Vec::new();
    for i in 1..=41 {
        if store.get(&key(i), "v1").await.is_some() {
            kept.push(i);
        }
    }
    seen.push(format!("{kept:?} {}", store.used().await <= 40 * COST));
    seen
}

#[tokio::test]
async fn sqlite_and_postgres_store_and_evict_tiles_alike() {
    let dir = tempfile::tempdir().unwrap();
    let pool = citymesh::db::open(dir.path().join("t.sqlite").to_str().unwrap())
        .await
        .unwrap();
    let sqlite = scenario(Store::Sqlite(
        TileStore::bounded(pool, 40 * COST).await.unwrap(),
    ))
    .await;
    let pg = common::postgres::Postgres::start();
    let pool = citymesh::db::open_postgres(&pg.url, 4).await.unwrap();
    let postgres = scenario(Store::Pg(PgTileStore::new(pool, 40 * COST))).await;
    println!("{sqlite:?}\n{postgres:?}");
    assert_eq!(sqlite, postgres);
}

//! Hostile files given to `citymesh import` (hardening round 3, item 4): one way whose node lies
//! far away, or whose node id is given twice, must not write a data tile for every tile its
//! bounding box covers; the building is skipped and reported by id; and an import is one
//! transaction, so one that stops midway leaves the store as it was.
#![allow(clippy::unwrap_used)] // test code: failing is the point

use citymesh::commands::import::import_into;
use citymesh::db::{self, Database};
use citymesh::source::data_tiles::OsmTileStore;
use citymesh_core::geo::TileCoord;
use serde_json::json;

/// An Overpass JSON file of one building way over `nodes` (id, lon, lat), closed on its first.
fn one_way(nodes: &[(i64, f64, f64)], way_nodes: &[i64]) -> Vec<u8> {
    let mut elements: Vec<_> = nodes
        .iter()
        .map(|&(id, lon, lat)| json!({"type": "node", "id": id, "lat": lat, "lon": lon}))
        .collect();
    elements.push(json!({
        "type": "way", "id": 77, "nodes": way_nodes, "tags": {"building": "yes"}
    }));
    serde_json::to_vec(&json!({"elements": elements})).unwrap()
}

async fn sqlite(dir: &tempfile::TempDir) -> Database {
    let path = dir.path().join("cache.db");
    Database::Sqlite(db::open(path.to_str().unwrap()).await.unwrap())
}

#[tokio::test]
async fn a_way_reaching_far_away_is_skipped_by_id_and_writes_no_data_tile() {
    let dir = tempfile::tempdir().unwrap();
    let db = sqlite(&dir).await;
    let square = [
        (1, 8.4000, 49.0100),
        (2, 8.4002, 49.0100),
        (3, 8.4002, 49.0102),
        (4, 8.4000, 49.0102),
    ];
    // One node 2 degrees east (about 146 km): a box of tens of thousands of data tiles.
    let mut far = square.to_vec();
    far[2] = (3, 10.4002, 49.0102);
    let far_file = dir.path().join("far.json");
    let bytes = one_way(&far, &[1, 2, 3, 4, 1]);
    assert!(bytes.len() < 600, "{} bytes", bytes.len());
    std::fs::write(&far_file, bytes).unwrap();
    let report = import_into(&[far_file], &db, true).await.unwrap();
    assert_eq!(report.buildings, 0);
    assert_eq!(report.skips, vec![("way/77".to_owned(), "too_large")]);
    assert_eq!(report.data_tiles, 0);
    assert_eq!(OsmTileStore::new(db.clone()).count().await.unwrap(), 0);

    // A node id given twice, the second far away (which one a reader keeps is not the point):
    // either the building is the small square or it is skipped; never a sea of tiles.
    let mut twice = square.to_vec();
    twice.push((3, 8.4002, 52.0102));
    let twice_file = dir.path().join("twice.json");
    std::fs::write(&twice_file, one_way(&twice, &[1, 2, 3, 4, 1])).unwrap();
    let report = import_into(&[twice_file], &db, true).await.unwrap();
    assert!(report.data_tiles <= 1, "{} data tiles", report.data_tiles);
    assert_eq!(report.buildings + report.skips.len(), 1);

    // A node out of range (latitude past Web Mercator's end) is skipped too.
    let mut polar = square.to_vec();
    polar[0] = (1, 8.4000, 89.0);
    let polar_file = dir.path().join("polar.json");
    std::fs::write(&polar_file, one_way(&polar, &[1, 2, 3, 4, 1])).unwrap();
    let report = import_into(&[polar_file], &db, true).await.unwrap();
    assert_eq!(report.skips, vec![("way/77".to_owned(), "out_of_range")]);
}

#[tokio::test]
async fn an_import_that_stops_before_its_commit_leaves_the_store_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let db = sqlite(&dir).await;
    let store = OsmTileStore::new(db.clone());
    let mut writer = store.import_writer().await.unwrap();
    for x in 0..3 {
        let t = TileCoord {
            z: 14,
            x: 8_600 + x,
            y: 5_600,
        };
        assert!(writer.put(&t, br#"{"elements":[]}"#).await.unwrap());
    }
    // Interrupted: dropped without its commit.
    drop(writer);
    assert_eq!(store.count().await.unwrap(), 0);
    let mut writer = store.import_writer().await.unwrap();
    let t = TileCoord {
        z: 14,
        x: 8_600,
        y: 5_600,
    };
    writer.put(&t, br#"{"elements":[]}"#).await.unwrap();
    writer.commit().await.unwrap();
    assert_eq!(store.count().await.unwrap(), 1);
}

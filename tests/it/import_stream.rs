//! `citymesh import` as a stream (issue 40): on the real files it stores exactly the data tiles
//! the whole-file path stored (the same records, bit for bit, in the same order), under a small
//! memory budget as under the default; a store of the old JSON layout serves the same GLB bytes
//! as a packed one; and bad files are refused by name, leaving the store as it was.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common::{self, app_with, data_dir, dem_dir, get};
use citymesh::commands::import::import_with;
use citymesh::db::{self, Database};
use citymesh::source::data_tiles::OsmTileStore;
use citymesh::source::data_tiles::import::ImportOptions;
use citymesh_core::building::cluster::record_bounds;
use citymesh_core::geo::TileCoord;
use citymesh_core::osm::{BuildingRecord, OsmId, read_buildings, unpack, write_overpass_json};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

const DATA_ZOOM: u8 = 14;

async fn sqlite(path: &Path) -> Database {
    Database::Sqlite(db::open(path.to_str().unwrap()).await.unwrap())
}

fn osm(name: &str) -> PathBuf {
    data_dir().join("osm").join(name)
}

/// The data tiles the whole-file import made (before issue 40): every file read whole, each
/// building once (the first file's), stored with every data tile its outline overlaps, by id.
fn whole_file_tiles(files: &[PathBuf]) -> BTreeMap<TileCoord, Vec<BuildingRecord>> {
    let mut seen = HashSet::new();
    let mut tiles: BTreeMap<TileCoord, Vec<BuildingRecord>> = BTreeMap::new();
    for f in files {
        let bytes = citymesh::source::read_osm_file(f).unwrap();
        for r in read_buildings(&bytes).unwrap().buildings {
            if !seen.insert(r.id) {
                continue;
            }
            let [x0, y0, x1, y1] = record_bounds(&r);
            let nw = TileCoord::containing(DATA_ZOOM, x0, y1);
            let se = TileCoord::containing(DATA_ZOOM, x1, y0);
            for x in nw.x..=se.x {
                for y in nw.y..=se.y {
                    tiles
                        .entry(TileCoord { z: DATA_ZOOM, x, y })
                        .or_default()
                        .push(r.clone());
                }
            }
        }
    }
    for records in tiles.values_mut() {
        records.sort_by_key(|r| r.id);
    }
    tiles
}

/// Every stored data tile, unpacked.
async fn stored(db: &Database) -> BTreeMap<TileCoord, Vec<BuildingRecord>> {
    let store = OsmTileStore::new(db.clone());
    let mut out = BTreeMap::new();
    for t in store.stored_tiles().await.unwrap() {
        let body = store.get(&t).await.unwrap().unwrap().body;
        let b = unpack(&body).unwrap();
        assert!(b.skipped.is_empty() && b.repaired.is_empty());
        out.insert(t, b.buildings);
    }
    out
}

/// A SQLite store at `path` holding Nuremberg, the data a failed import must leave as it was.
async fn nuremberg_store(path: &Path, temp: &Path) -> Database {
    let db = sqlite(path).await;
    import_with(&[osm("nuremberg-laufamholz.osm")], &db, &options(64, temp))
        .await
        .unwrap();
    db
}

fn coordinate_bits(tiles: &BTreeMap<TileCoord, Vec<BuildingRecord>>) -> Vec<u64> {
    tiles
        .values()
        .flatten()
        .flat_map(|r| r.outers.iter().chain(&r.inners))
        .flat_map(|r| &r.nodes)
        .flat_map(|n| [n.lon.to_bits(), n.lat.to_bits()])
        .collect()
}

fn options(memory_mb: u64, temp: &Path) -> ImportOptions {
    ImportOptions {
        memory_bytes: memory_mb << 20,
        temp_dir: Some(temp.to_owned()),
        quiet: true,
    }
}

#[tokio::test]
async fn every_real_file_streams_into_exactly_the_data_tiles_the_whole_file_path_stored() {
    let cases: &[(&[&str], usize)] = &[
        (&["karlsruhe-kirchfeld.osm.pbf"], 3026),
        (&["karlsruhe-kit-nord.osm.pbf"], 602),
        (&["tram-junction.osm.pbf"], 280),
        (&["nuremberg-laufamholz.osm"], 118),
        (&["san-francisco.overpass.json.gz"], 617),
        (&["karlsruhe-kirchfeld.overpass.json"], 3026),
        // Several files at once; Kirchfeld twice (first as PBF): each building once.
        (
            &[
                "karlsruhe-kirchfeld.osm.pbf",
                "karlsruhe-kit-nord.osm.pbf",
                "karlsruhe-kirchfeld.overpass.json",
            ],
            3026 + 602,
        ),
    ];
    for (names, buildings) in cases {
        let files: Vec<PathBuf> = names.iter().map(|n| osm(n)).collect();
        let expected = whole_file_tiles(&files);
        // The default budget, and the smallest one (node blocks mostly read from disk).
        for memory_mb in [1024, 16] {
            let dir = tempfile::tempdir().unwrap();
            let db = sqlite(&dir.path().join("c.sqlite")).await;
            let report = import_with(&files, &db, &options(memory_mb, dir.path()))
                .await
                .unwrap();
            let label = format!("{names:?} at {memory_mb} MB");
            assert_eq!(report.buildings, *buildings, "{label}");
            assert_eq!(report.skipped, 0, "{label}");
            assert_eq!(report.data_tiles, expected.len(), "{label}");
            // The compact store: well under 250 bytes per building (578 as JSON before).
            assert!(
                report.stored_bytes <= 100 * report.buildings as u64,
                "{label}: {} bytes",
                report.stored_bytes
            );
            let got = stored(&db).await;
            assert_eq!(
                got.keys().collect::<Vec<_>>(),
                expected.keys().collect::<Vec<_>>(),
                "{label}"
            );
            assert_eq!(coordinate_bits(&got), coordinate_bits(&expected), "{label}");
            assert_eq!(got, expected, "{label}");
            // Nothing left behind in the temporary directory but the database.
            let left: Vec<_> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .filter(|n| !n.starts_with("c.sqlite"))
                .collect();
            assert!(left.is_empty(), "{label}: {left:?}");
        }
    }
}

#[tokio::test]
async fn every_multipolygon_keeps_its_member_ways_in_each_of_its_data_tiles() {
    // What a later change to a member way must find: the relation it draws. Kirchfeld's five
    // building multipolygons and their way members, as `osmium tags-filter -R` lists them.
    let expected: BTreeMap<i64, Vec<i64>> = [
        (1_776_559, vec![241_090_748, 132_344_585]),
        (3_229_490, vec![132_367_023, 239_467_076, 239_467_075]),
        (9_331_926, vec![132_344_549, 670_977_182]),
        (9_331_927, vec![670_977_188, 132_344_542]),
        (11_893_189, vec![667_906_615, 871_745_678]),
    ]
    .into();
    for file in [
        "karlsruhe-kirchfeld.osm.pbf",
        "karlsruhe-kirchfeld.overpass.json",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let db = sqlite(&dir.path().join("c.sqlite")).await;
        import_with(&[osm(file)], &db, &options(16, dir.path()))
            .await
            .unwrap();
        let store = OsmTileStore::new(db.clone());
        let mut seen: BTreeMap<i64, Vec<i64>> = BTreeMap::new();
        for t in store.stored_tiles().await.unwrap() {
            let b = unpack(&store.get(&t).await.unwrap().unwrap().body).unwrap();
            let relations: Vec<i64> = b
                .buildings
                .iter()
                .filter_map(|r| match r.id {
                    OsmId::Relation(id) => Some(id),
                    OsmId::Way(_) => None,
                })
                .collect();
            // Exactly the tile's multipolygons, each once, by id.
            let listed: Vec<i64> = b.member_ways.iter().map(|m| m.relation).collect();
            assert_eq!(listed, relations, "{file} {t:?}");
            for m in b.member_ways {
                let before = seen.insert(m.relation, m.ways.clone());
                assert!(before.is_none_or(|w| w == m.ways), "{file} {t:?}");
            }
        }
        assert_eq!(seen, expected, "{file}");
    }
}

#[tokio::test]
async fn a_store_of_the_old_json_layout_serves_the_same_glb_bytes_as_a_packed_one() {
    let dir = tempfile::tempdir().unwrap();
    let pbf = osm("karlsruhe-kirchfeld.osm.pbf");
    // The old layout: each data tile as Overpass JSON, as imports wrote it before issue 40.
    let old_file = dir.path().join("old.sqlite");
    let old = sqlite(&old_file).await;
    let mut writer = OsmTileStore::new(old.clone())
        .import_writer()
        .await
        .unwrap();
    for (t, records) in whole_file_tiles(std::slice::from_ref(&pbf)) {
        let refs: Vec<&BuildingRecord> = records.iter().collect();
        writer.put(&t, &write_overpass_json(&refs)).await.unwrap();
    }
    writer.commit().await.unwrap();
    let new_file = dir.path().join("new.sqlite");
    let new = sqlite(&new_file).await;
    import_with(&[pbf], &new, &options(1024, dir.path()))
        .await
        .unwrap();
    let (old_app, new_app) = (
        app_with(&dem_dir(), &old_file, &["--offline"]).await,
        app_with(&dem_dir(), &new_file, &["--offline"]).await,
    );
    let mut uris = vec!["/tiles/15/17147/11245.glb".to_owned()];
    for x in 34295..34298 {
        for y in 22490..22493 {
            uris.push(format!("/tiles/16/{x}/{y}.glb"));
        }
    }
    uris.push("/scene?bbox=8.33,49.025,8.35,49.04".to_owned());
    let mut buildings = 0;
    for uri in &uris {
        let (a, b) = (get(&old_app, uri).await, get(&new_app, uri).await);
        assert_eq!(a.status, 200, "{uri}: {}", a.text());
        assert_eq!(b.status, 200, "{uri}: {}", b.text());
        common::assert_valid_glb(&b.body);
        assert!(
            a.body == b.body,
            "{uri}: {} against {} bytes",
            a.body.len(),
            b.body.len()
        );
        buildings += b
            .header("x-citymesh-buildings")
            .parse::<usize>()
            .unwrap_or(0);
    }
    assert!(buildings > 1_000, "{buildings} buildings drawn");
}

/// The blocks of a PBF file: (offset, length) of each, header first.
fn blocks(path: &Path) -> Vec<(u64, u64)> {
    let mut reader = osmpbf::BlobReader::seekable_from_path(path).unwrap();
    let mut starts = Vec::new();
    while let Some(next) = reader.next_header_skip_blob() {
        starts.push(next.unwrap().1.unwrap().0);
    }
    let len = std::fs::metadata(path).unwrap().len();
    starts
        .iter()
        .enumerate()
        .map(|(i, s)| (*s, starts.get(i + 1).copied().unwrap_or(len) - s))
        .collect()
}

/// What the store holds, as (tile, hash) rows.
async fn rows(db: &Database) -> Vec<(TileCoord, String)> {
    let store = OsmTileStore::new(db.clone());
    let mut out = Vec::new();
    for t in store.stored_tiles().await.unwrap() {
        out.push((t, store.get(&t).await.unwrap().unwrap().hash));
    }
    out
}

#[tokio::test]
async fn bad_pbf_files_are_refused_by_name_and_leave_the_store_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    // What is there before: Nuremberg.
    let db = nuremberg_store(&dir.path().join("c.sqlite"), dir.path()).await;
    let before = rows(&db).await;
    assert_eq!(before.len(), 1);

    let src = osm("karlsruhe-kirchfeld.osm.pbf");
    let bytes = std::fs::read(&src).unwrap();
    let b = blocks(&src);
    assert!(b.len() >= 5, "{} blocks", b.len());
    let block = |i: usize| &bytes[b[i].0 as usize..(b[i].0 + b[i].1) as usize];
    let write = |name: &str, parts: &[&[u8]]| {
        let path = dir.path().join(name);
        std::fs::write(&path, parts.concat()).unwrap();
        path
    };
    let middle = b[b.len() / 2];
    let flipped = {
        let mut c = bytes.clone();
        let at = (middle.0 + middle.1 / 2) as usize;
        for v in &mut c[at..at + 64] {
            *v ^= 0x5a;
        }
        c
    };
    let cases = [
        // Cut in the middle of a block.
        (
            write(
                "cut.osm.pbf",
                &[&bytes[..(middle.0 + middle.1 / 2) as usize]],
            ),
            "corrupt or truncated",
        ),
        // Bytes changed inside a block's compressed data.
        (
            write("flipped.osm.pbf", &[&flipped]),
            "corrupt or truncated",
        ),
        // Two node blocks swapped: an id out of order.
        (
            write(
                "swapped.osm.pbf",
                &[
                    &[block(0), block(2), block(1)].concat(),
                    &bytes[b[3].0 as usize..],
                ],
            ),
            "is not sorted by id",
        ),
        // The last block (relations) first: relations before ways.
        (
            write(
                "relations-first.osm.pbf",
                &[
                    block(0),
                    block(b.len() - 1),
                    &bytes[b[1].0 as usize..b[b.len() - 1].0 as usize],
                ],
            ),
            "not sorted",
        ),
        // Not a PBF file past its first bytes.
        (
            write("header-only.osm.pbf", &[&bytes[..(b[0].1 as usize + 10)]]),
            "corrupt or truncated",
        ),
    ];
    for (path, why) in &cases {
        let e = import_with(std::slice::from_ref(path), &db, &options(64, dir.path()))
            .await
            .unwrap_err();
        let e = format!("{e:#}");
        assert!(e.contains(&path.display().to_string()), "{e}");
        assert!(e.contains(why), "{path:?}: {e}");
        assert_eq!(rows(&db).await, before, "{path:?}");
    }

    // Ways whose nodes are missing (the node blocks left out): each building is skipped by id
    // with its reason, and nothing is stored for it.
    let first_way_block = (1..b.len())
        .find(|i| {
            let path = write("probe.osm.pbf", &[block(0), block(*i)]);
            let mut ways = 0;
            osmpbf::ElementReader::from_path(&path)
                .unwrap()
                .for_each(|e| ways += usize::from(matches!(e, osmpbf::Element::Way(_))))
                .unwrap();
            ways > 0
        })
        .unwrap();
    let no_nodes = write(
        "no-nodes.osm.pbf",
        &[block(0), &bytes[b[first_way_block].0 as usize..]],
    );
    let report = import_with(&[no_nodes], &db, &options(64, dir.path()))
        .await
        .unwrap();
    assert_eq!(report.data_tiles, 0);
    assert!(report.skipped > 2_000, "{} skipped", report.skipped);
    assert!(report.skips.iter().all(|(id, why)| {
        (id.starts_with("way/") || id.starts_with("relation/"))
            && ["missing_nodes", "missing_members", "too_few_nodes"].contains(why)
    }));
    assert_eq!(rows(&db).await, before);
}

#[tokio::test]
async fn a_disk_that_fills_up_fails_the_import_by_name_and_leaves_the_store_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("c.sqlite");
    let db = nuremberg_store(&file, dir.path()).await;
    let before = rows(&db).await;
    if let Database::Sqlite(pool) = &db {
        pool.close().await;
    }
    // Files this process writes may grow to 256 KB: Kirchfeld's node locations alone take
    // 470 KB. Writing past it fails as on a full disk (the signal that would kill is ignored).
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f 512; exec {} import --quiet --cache-db {} --temp-dir {} {}",
            env!("CARGO_BIN_EXE_citymesh"),
            file.display(),
            dir.path().display(),
            osm("karlsruhe-kirchfeld.osm.pbf").display()
        ))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("karlsruhe-kirchfeld.osm.pbf"), "{stderr}");
    assert!(stderr.contains("File too large"), "{stderr}");
    let db = sqlite(&file).await;
    assert_eq!(rows(&db).await, before);
}

#[tokio::test]
async fn postgresql_takes_the_import_in_bulk_and_holds_exactly_what_sqlite_holds() {
    let pg = common::postgres::Postgres::start();
    let dir = tempfile::tempdir().unwrap();
    let lite = sqlite(&dir.path().join("c.sqlite")).await;
    let postgres = Database::Postgres(db::open_postgres(&pg.url, 4).await.unwrap());
    let files = [
        osm("karlsruhe-kirchfeld.osm.pbf"),
        osm("karlsruhe-kit-nord.osm.pbf"),
    ];
    let opts = options(16, dir.path());
    let on_sqlite = import_with(&files, &lite, &opts).await.unwrap();
    let on_postgres = import_with(&files, &postgres, &opts).await.unwrap();
    assert_eq!(on_postgres.buildings, 3026 + 602);
    assert_eq!(on_postgres.data_tiles, on_sqlite.data_tiles);
    assert_eq!(on_postgres.changed_data_tiles, on_postgres.data_tiles);
    assert_eq!(rows(&postgres).await, rows(&lite).await);
    assert_eq!(stored(&postgres).await, whole_file_tiles(&files));

    // The same files again: the hashes each bulk write replaced are the tiles' own.
    let again = import_with(&files, &postgres, &opts).await.unwrap();
    assert_eq!(
        (again.data_tiles, again.changed_data_tiles),
        (on_sqlite.data_tiles, 0)
    );
    // One file changed: exactly the data tiles under it change.
    let kirchfeld = import_with(&files[..1], &postgres, &opts).await.unwrap();
    let only = import_with(&files[..1], &lite, &opts).await.unwrap();
    assert_eq!(kirchfeld.changed_data_tiles, only.changed_data_tiles);
    assert_eq!(rows(&postgres).await, rows(&lite).await);
}

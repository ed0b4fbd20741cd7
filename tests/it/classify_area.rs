//! Roofs classified from imagery end to end: a real imagery server started inside the test on
//! 127.0.0.1 serves XYZ tiles that citymesh's renderer draws of real Kirchfeld footprints with
//! the roof shapes their tags say (a synthetic orthophoto); citymesh classifies the buildings from
//! it and the predictions are compared with the tags. Bad imagery fails buildings, not the run.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use citymesh::commands::classify::agreement;
use citymesh::roofs::classifier::{Passes, RoofClassifier, load_classifier};
use citymesh::roofs::imagery::{Imagery, ImagerySpec};
use citymesh::roofs::jobs::worker::{WorkerConfig, run_round};
use citymesh::roofs::jobs::{JobQueue, Selection, select_buildings};
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::{BuildingRecord, read_buildings};
use std::collections::HashMap;
use std::sync::Arc;

/// The area: about 500 x 650 m of Kirchfeld with many flat and gabled tags.
const AREA: &str = "8.396,49.052,8.403,49.058";

fn kirchfeld() -> Vec<BuildingRecord> {
    let area: GeoBbox = AREA.parse().unwrap();
    let mut records = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    records.retain(|r| {
        let n = &r.outers[0].nodes[0];
        area.contains(n.lon, n.lat)
    });
    records
}

/// Queues every selected building of `records` and runs rounds until none is left; returns the
/// batch's job counts by state and the predictions with their buildings' tags.
async fn classify(
    records: &[BuildingRecord],
    imagery: &Imagery,
    classifier: &Arc<dyn RoofClassifier>,
) -> (
    std::collections::BTreeMap<String, u64>,
    Vec<(Option<String>, citymesh::roofs::classifier::Prediction)>,
) {
    let queue = JobQueue::new(&citymesh::db::Database::Sqlite(
        citymesh::db::open(":memory:").await.unwrap(),
    ));
    let (jobs, _) = select_buildings(records, Selection::All);
    let (batch, counts) = queue
        .enqueue(
            AREA,
            &imagery.spec().id,
            classifier.model_id(),
            &jobs,
            Default::default(),
        )
        .await
        .unwrap();
    assert_eq!(counts.queued as usize, jobs.len());
    while run_round(
        &queue,
        imagery,
        classifier,
        WorkerConfig::default(),
        &|_, _, _| {},
    )
    .await
    .unwrap()
    .is_some()
    {}
    let progress = queue.progress(&batch).await.unwrap().unwrap();
    assert!(progress.finished);
    let tags: HashMap<String, Option<String>> = records
        .iter()
        .map(|r| (r.id.to_string(), r.tags.get("roof:shape").cloned()))
        .collect();
    let predictions = queue
        .predictions(&AREA.parse().unwrap(), u32::MAX)
        .await
        .unwrap()
        .into_iter()
        .map(|p| (tags.get(&p.osm_id).cloned().flatten(), p.prediction))
        .collect();
    (progress.jobs, predictions)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kirchfeld_roofs_classified_from_rendered_imagery_agree_with_their_tags() {
    let base = common::imagery::imagery_server().await;
    let records = kirchfeld();
    let classifier = load_classifier(None, None, Passes::default()).unwrap();
    let imagery = Imagery::open(ImagerySpec::xyz(
        "ortho",
        &format!("{base}/ortho/{{z}}/{{x}}/{{y}}.png"),
    ))
    .await
    .unwrap();
    let (jobs, predictions) = classify(&records, &imagery, &classifier).await;
    assert_eq!(jobs["failed"], 0, "{jobs:?}");
    let text = agreement(&predictions);
    eprintln!("{} roofs classified; {text}", predictions.len());
    let compared = predictions
        .iter()
        .filter(|(t, _)| {
            matches!(
                t.as_deref(),
                Some("flat" | "gabled" | "hipped" | "pyramidal")
            )
        })
        .count();
    let agree = predictions
        .iter()
        .filter(|(t, p)| {
            t.as_deref()
                .and_then(citymesh_core::building::roof::RoofShape::from_tag)
                .and_then(citymesh_core::roof_image::RoofClass::of_shape)
                == Some(p.class())
        })
        .count();
    assert!(compared >= 100, "{compared}");
    let share = agree as f64 / compared as f64;
    assert!(share >= 0.80, "{text}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_imagery_fails_jobs_with_a_reason_and_never_the_run() {
    let base = common::imagery::imagery_server().await;
    let records: Vec<BuildingRecord> = kirchfeld()
        .into_iter()
        .filter(|r| !r.is_part)
        .take(3)
        .collect();
    let classifier = load_classifier(None, None, Passes::default()).unwrap();
    for kind in ["missing", "garbage", "huge", "hang", "small"] {
        let mut spec = ImagerySpec::xyz(kind, &format!("{base}/{kind}/{{z}}/{{x}}/{{y}}.png"));
        spec.timeout_s = 1.0;
        spec.retries = 0;
        let imagery = Imagery::open(spec).await.unwrap();
        // A hang costs the timeout per attempt, so the run ends; 120 s turns a regression into a
        // failure instead of a stuck test.
        let (jobs, predictions) = tokio::time::timeout(
            std::time::Duration::from_secs(120),
            classify(&records, &imagery, &classifier),
        )
        .await
        .unwrap_or_else(|_| panic!("{kind}: classification did not end"));
        assert_eq!(jobs["failed"], 3, "{kind}: {jobs:?}");
        assert!(predictions.is_empty(), "{kind}");
    }
}

/// Writes an MBTiles file of `tiles` (PNG bytes by z, x, y).
async fn write_mbtiles(path: &std::path::Path, tiles: &HashMap<(u8, u32, u32), Vec<u8>>) {
    use sqlx::sqlite::SqliteConnectOptions;
    let pool = sqlx::SqlitePool::connect_with(
        SqliteConnectOptions::new()
            .filename(path)
            .create_if_missing(true),
    )
    .await
    .unwrap();
    sqlx::query("CREATE TABLE metadata (name TEXT, value TEXT)")
        .execute(&pool)
        .await
        .unwrap();
    sqlx::query(
        "CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, \
         tile_data BLOB)",
    )
    .execute(&pool)
    .await
    .unwrap();
    for (&(z, x, y), png) in tiles {
        sqlx::query("INSERT INTO tiles VALUES (?, ?, ?, ?)")
            .bind(i64::from(z))
            .bind(i64::from(x))
            .bind((1i64 << z) - 1 - i64::from(y))
            .bind(png)
            .execute(&pool)
            .await
            .unwrap();
    }
    pool.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wms_and_mbtiles_sources_give_the_crops_xyz_gives() {
    let (base, ortho) = common::imagery::imagery_server_with_tiles().await;
    let records: Vec<BuildingRecord> = kirchfeld()
        .into_iter()
        .filter(|r| !r.is_part)
        .take(24)
        .collect();
    let classifier = load_classifier(None, None, Passes::default()).unwrap();
    let open =
        |url: String| async move { Imagery::open(ImagerySpec::xyz("same", &url)).await.unwrap() };
    let xyz = open(format!("{base}/ortho/{{z}}/{{x}}/{{y}}.png")).await;
    let (jobs, from_xyz) = classify(&records, &xyz, &classifier).await;
    assert_eq!(jobs["done"], 24, "{jobs:?}");
    let wms = open(format!(
        "{base}/wms?SERVICE=WMS&REQUEST=GetMap&SRS=EPSG:3857&BBOX={{bbox}}&WIDTH={{width}}&HEIGHT={{height}}"
    ))
    .await;
    let (_, from_wms) = classify(&records, &wms, &classifier).await;
    // Every tile the runs fetched, as a local MBTiles file.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ortho.mbtiles");
    let tiles = ortho.tiles.lock().unwrap().clone();
    write_mbtiles(&file, &tiles).await;
    let mbtiles = open(file.to_str().unwrap().to_owned()).await;
    let (_, from_mbtiles) = classify(&records, &mbtiles, &classifier).await;
    let probabilities = |v: &[(Option<String>, citymesh::roofs::classifier::Prediction)]| {
        v.iter().map(|(_, p)| p.probabilities).collect::<Vec<_>>()
    };
    assert_eq!(probabilities(&from_wms), probabilities(&from_xyz));
    assert_eq!(probabilities(&from_mbtiles), probabilities(&from_xyz));
    // An MBTiles file without the tile fails the job as a 404 would.
    let empty = dir.path().join("empty.mbtiles");
    write_mbtiles(&empty, &HashMap::new()).await;
    let none = open(empty.to_str().unwrap().to_owned()).await;
    let (jobs, _) = classify(&records[..2], &none, &classifier).await;
    assert_eq!(jobs["failed"], 2, "{jobs:?}");
}

/// Writes the orthophoto's zoom-19 tiles over `area` as one RGB GeoTIFF in EPSG:3857 (strips of
/// 64 rows), exactly their pixels.
async fn write_mercator_geotiff(path: &std::path::Path, base: &str, area: &GeoBbox) {
    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;
    const HALF: f64 = 20_037_508.342_789_244;
    let range = citymesh_core::geo::TileCoord::covering(area, 19);
    let tiles: Vec<_> = range.tiles().collect();
    let (x0, y0) = (
        tiles.iter().map(|t| t.x).min().unwrap(),
        tiles.iter().map(|t| t.y).min().unwrap(),
    );
    let (x1, y1) = (
        tiles.iter().map(|t| t.x).max().unwrap(),
        tiles.iter().map(|t| t.y).max().unwrap(),
    );
    let (w, h) = ((x1 - x0 + 1) * 256, (y1 - y0 + 1) * 256);
    let mut data = vec![0u8; (w * h * 3) as usize];
    for t in &tiles {
        let png = reqwest::get(format!("{base}/ortho/19/{}/{}.png", t.x, t.y))
            .await
            .unwrap()
            .bytes()
            .await
            .unwrap();
        let rgb = image::load_from_memory(&png).unwrap().into_rgb8();
        for (px, py, p) in rgb.enumerate_pixels() {
            let (gx, gy) = ((t.x - x0) * 256 + px, (t.y - y0) * 256 + py);
            let at = ((gy * w + gx) * 3) as usize;
            data[at..at + 3].copy_from_slice(&p.0);
        }
    }
    let side = 2.0 * HALF / f64::from(1u32 << 19);
    let origin = [-HALF + f64::from(x0) * side, HALF - f64::from(y0) * side];
    let mut encoder = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    let mut image = encoder.new_image::<colortype::RGB8>(w, h).unwrap();
    image.rows_per_strip(64).unwrap();
    let dir = image.encoder();
    let scale = side / 256.0;
    dir.write_tag(Tag::Unknown(33_550), &[scale, scale, 0.0][..])
        .unwrap();
    dir.write_tag(
        Tag::Unknown(33_922),
        &[0.0, 0.0, 0.0, origin[0], origin[1], 0.0][..],
    )
    .unwrap();
    dir.write_tag(
        Tag::Unknown(34_735),
        &[1u16, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 3857][..],
    )
    .unwrap();
    image.write_data(&data).unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_geotiff_source_classifies_as_the_tiles_it_was_made_of() {
    let base = common::imagery::imagery_server().await;
    let records: Vec<BuildingRecord> = kirchfeld()
        .into_iter()
        .filter(|r| !r.is_part)
        .take(24)
        .collect();
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for n in records.iter().flat_map(|r| &r.outers[0].nodes) {
        lo = [lo[0].min(n.lon), lo[1].min(n.lat)];
        hi = [hi[0].max(n.lon), hi[1].max(n.lat)];
    }
    let area = GeoBbox::new(lo[0], lo[1], hi[0], hi[1])
        .unwrap()
        .grown_by_metres(80.0);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ortho-3857.tif");
    write_mercator_geotiff(&file, &base, &area).await;
    let classifier = load_classifier(None, None, Passes::default()).unwrap();
    let mut spec = ImagerySpec::xyz("ortho", &format!("{base}/ortho/{{z}}/{{x}}/{{y}}.png"));
    spec.max_zoom = 19;
    let xyz = Imagery::open(spec).await.unwrap();
    let geotiff = Imagery::open(ImagerySpec::xyz("tif", file.to_str().unwrap()))
        .await
        .unwrap();
    // The file's pixels are zoom 19's: the zoom it offers.
    assert_eq!(geotiff.spec().max_zoom, 19);
    let (jobs, from_xyz) = classify(&records, &xyz, &classifier).await;
    let (tif_jobs, from_tif) = classify(&records, &geotiff, &classifier).await;
    assert_eq!((jobs["done"], tif_jobs["done"]), (24, 24), "{tif_jobs:?}");
    // Crops at zoom 19 are the same pixels; those at a lower zoom are resampled from zoom 19
    // here and rendered at that zoom by the server: the classes agree.
    let same = from_xyz
        .iter()
        .zip(&from_tif)
        .filter(|(a, b)| a.1.class() == b.1.class())
        .count();
    eprintln!("GeoTIFF and XYZ agree on {same} of 24 buildings");
    assert!(same >= 22, "{same}");
}

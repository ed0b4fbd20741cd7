//! The roof classifier together with the roof prior (docs/extensions.md section 4): Kirchfeld with
//! the roof tags of half its tagged buildings removed (even ids, as `tests/it/roof_prior.rs`), an
//! imagery server started by the test drawing every building with the shape its real tags say,
//! and the buildings of a part of the area classified through the server. On the hidden
//! buildings there, the classifier alone, the prior alone and their combination (the normalised
//! product `roofs=classified` uses) are counted against the real tags; the combination gets
//! more right than either (exact counts), and the server's classified roofs are the
//! combination's.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh::roofs::jobs::worker::WorkerConfig;
use citymesh_core::learn::cross_validation::argmax;
use citymesh_core::osm::{BuildingRecord, OsmId, read_buildings, write_overpass_json};
use citymesh_core::roof_image::RoofClass;
use citymesh_core::roof_prior::{RoofPrior, combine, tagged_class};
use std::collections::HashMap;
use std::time::Duration;

/// The part classified: where most of Kirchfeld's tags are.
const PART: &str = "8.3960,49.0520,8.4030,49.0580";
/// Hidden buildings of the part with a prediction, and those the classifier alone, the prior
/// alone and the combination get right.
const COUNTS: (usize, usize, usize, usize) = (160, 157, 156, 159);

fn numeric(id: OsmId) -> i64 {
    match id {
        OsmId::Way(i) | OsmId::Relation(i) => i,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_classifier_and_the_prior_together_beat_each_alone() {
    let dir = tempfile::tempdir().unwrap();
    let truth = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let mut hidden: HashMap<String, RoofClass> = HashMap::new();
    let served: Vec<BuildingRecord> = truth
        .iter()
        .cloned()
        .map(|mut r| {
            if let Some(c) = tagged_class(&r).filter(|_| numeric(r.id) % 2 == 0 && !r.is_part) {
                r.tags.remove("roof:shape");
                hidden.insert(r.id.to_string(), c);
            }
            r
        })
        .collect();
    let refs: Vec<&BuildingRecord> = served.iter().collect();
    let osm = dir.path().join("kirchfeld-half.json");
    std::fs::write(&osm, write_overpass_json(&refs)).unwrap();
    let prior = RoofPrior::fit(&refs);

    let imagery = common::imagery::imagery_server().await;
    let args = common::imagery::classifying_args(
        &dir.path().join("c.sqlite"),
        &osm,
        &format!("{imagery}/ortho/{{z}}/{{x}}/{{y}}"),
        "ortho",
    );
    let state = citymesh::server::build_state(&args).await.unwrap();
    assert!(state.classifier.is_some(), "the classifier did not load");
    state
        .generator
        .roofs
        .spawn_workers(1, WorkerConfig::default());
    let app = citymesh::app(state.clone());

    let created = common::post_json(&app, "/classify", serde_json::json!({ "bbox": PART })).await;
    assert_eq!(created.status, StatusCode::ACCEPTED, "{}", created.text());
    let id = created.json()["id"].as_str().unwrap().to_owned();
    let deadline = std::time::Instant::now() + Duration::from_secs(900);
    loop {
        let progress = common::get(&app, &format!("/classify/{id}")).await.json();
        if progress["finished"] == true {
            break;
        }
        assert!(std::time::Instant::now() < deadline, "{progress}");
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    let predictions = common::get(&app, &format!("/classify/predictions?bbox={PART}"))
        .await
        .json();
    let (mut count, mut image, mut alone, mut both) = (0, 0, 0, 0);
    let mut combined_of: HashMap<String, [f32; 3]> = HashMap::new();
    for f in predictions["features"].as_array().unwrap() {
        let p = &f["properties"];
        let osm_id = p["osm_id"].as_str().unwrap();
        let from_image: [f32; 3] =
            RoofClass::ALL.map(|c| p["probabilities"][c.name()].as_f64().unwrap() as f32);
        let record = served.iter().find(|r| r.id.to_string() == osm_id).unwrap();
        let Some(from_prior) = prior.probabilities(&record.id) else {
            continue;
        };
        let combined = combine(from_image, from_prior);
        combined_of.insert(osm_id.to_owned(), combined);
        let Some(truth) = hidden.get(osm_id) else {
            continue;
        };
        let t = truth.index();
        count += 1;
        image += usize::from(argmax(&from_image) == t);
        alone += usize::from(argmax(&from_prior) == t);
        both += usize::from(argmax(&combined) == t);
    }
    eprintln!(
        "hidden buildings of the part: {count}; right: classifier {image}, prior {alone}, both {both}"
    );
    assert_eq!((count, image, alone, both), COUNTS);
    assert!(both > image && both > alone);

    // The server's classified roofs are the combination's.
    let stats = common::get(&app, &format!("/scene/stats?bbox={PART}&roofs=classified"))
        .await
        .json();
    let figures = &stats["classified_roofs"];
    eprintln!("classified roofs: {figures}");
    // Every prediction met the prior (one prior over the file applies everywhere).
    let n = |k: &str| figures[k].as_u64().unwrap();
    assert_eq!(n("with_prior"), n("classified") + n("uncertain"));
    assert!(n("with_prior") >= 160);
    let t = citymesh_core::geo::TileCoord::containing(16, 8.3995, 49.0550);
    let tile = common::get(
        &app,
        &format!("/tiles/16/{}/{}.glb?roofs=classified", t.x, t.y),
    )
    .await;
    assert_eq!(tile.status, StatusCode::OK);
    let mut checked = 0;
    for row in common::decode::feature_rows(&tile.body) {
        if row["roof_source"] != "classifier" {
            continue;
        }
        let id = format!(
            "{}/{}",
            row["osm_type"].as_str().unwrap(),
            row["osm_id"].as_str().unwrap()
        );
        let combined = combined_of[&id];
        let c = argmax(&combined);
        assert_eq!(row["roof_shape"], RoofClass::ALL[c].name(), "{id}");
        let written: f32 = row["roof_probability"].as_str().unwrap().parse().unwrap();
        assert!(
            (written - combined[c]).abs() < 2e-3,
            "{id}: {written} {combined:?}"
        );
        checked += 1;
    }
    assert!(checked > 10, "{checked} classified roofs in the tile");
}

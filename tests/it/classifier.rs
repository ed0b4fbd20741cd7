//! The roof classifier for real: the committed ONNX model run by ONNX Runtime (the library from
//! the PyPI wheel that scripts/test installs into .venv), on crops citymesh renders with a seed
//! and footprints that training never saw.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use citymesh::roofs::classifier::input::crop_image;
use citymesh::roofs::classifier::training_set::write_png;
use citymesh::roofs::classifier::{
    MODEL, MODEL_RULE, Passes, RoofClassifier, load_classifier, model_id_of,
};
use citymesh_core::osm::read_buildings;
use citymesh_core::roof_image::RoofClass;
use citymesh_core::roof_image::synthetic::{FootprintPool, Palette, render_sample};
use std::sync::Arc;

fn classifier() -> Arc<dyn RoofClassifier> {
    classifier_with(Passes::default())
}

fn classifier_with(passes: Passes) -> Arc<dyn RoofClassifier> {
    load_classifier(None, None, passes).unwrap_or_else(|e| {
        panic!("{e}\n(scripts/test installs onnxruntime into .venv; run it once)")
    })
}

/// Footprints neither the training nor the test set drew from in this combination: Kirchfeld's
/// real outlines and a procedural city of a seed training did not use.
fn pools() -> Vec<FootprintPool> {
    let kirchfeld = read_buildings(&common::osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    vec![
        FootprintPool::from_records(&kirchfeld.buildings),
        FootprintPool::procedural(21),
    ]
}

#[test]
fn the_model_id_is_the_sha256_the_model_card_states() {
    let card = std::fs::read_to_string("training/roof_classifier/MODEL_CARD.md").unwrap();
    let id = model_id_of(MODEL);
    assert!(
        card.contains(&format!("`{id}`")),
        "MODEL_CARD.md does not state the committed model's sha256 {id}"
    );
    assert_eq!(classifier().model_id(), id);
    assert_eq!(id.len(), 64);
}

#[test]
fn held_out_renders_are_classified_at_least_80_percent_right() {
    // 600 crops in the held-out palette, with a seed no set used; classes balanced.
    let pools = pools();
    let mut crops = Vec::new();
    let mut truth = Vec::new();
    for i in 0..600u64 {
        let sample = render_sample(
            &pools[(i / 3) as usize % 2],
            7_000_000 + i,
            Palette::Holdout,
            MODEL_RULE,
        )
        .expect("a sample");
        truth.push(sample.class);
        crops.push(sample.crop);
    }
    let predictions = classifier().classify(&crops).unwrap();
    let mut confusion = [[0u32; 3]; 3];
    for (t, p) in truth.iter().zip(&predictions) {
        confusion[t.index()][p.class().index()] += 1;
    }
    let right: u32 = (0..3).map(|i| confusion[i][i]).sum();
    let accuracy = f64::from(right) / 600.0;
    eprintln!("accuracy {accuracy:.3}, confusion (rows truth flat/gabled/hipped) {confusion:?}");
    // 89.8 % when measured (the model card gives 91.2 % on its 3,000 held-out crops); 80 %
    // leaves room for ONNX Runtime builds that round differently and still catches a broken
    // model, crop rule or input order (which fall to a third).
    assert!(
        accuracy >= 0.80,
        "accuracy {accuracy:.3}, confusion {confusion:?}"
    );
}

#[test]
fn probabilities_sum_to_one_and_batches_answer_as_single_crops() {
    let pools = pools();
    // 70 crops: several batches of 16.
    let crops: Vec<_> = (0..70u64)
        .map(|i| {
            render_sample(&pools[1], 9_000 + i, Palette::Training, MODEL_RULE)
                .unwrap()
                .crop
        })
        .collect();
    let mut answers = Vec::new();
    for passes in [Passes::Shifted, Passes::Turns] {
        answers.push(batches_answer_as_single_crops(
            &classifier_with(passes),
            &crops,
        ));
    }
    // The shifts change the probabilities (they are run) but rarely the class.
    let (shifted, turns) = (&answers[0], &answers[1]);
    assert!(shifted.iter().zip(turns).any(|(a, b)| a != b));
    let same = shifted
        .iter()
        .zip(turns)
        .filter(|(a, b)| a.class() == b.class())
        .count();
    assert!(
        same >= 63,
        "{same} of 70 crops keep their class without the shifts"
    );
}

fn batches_answer_as_single_crops(
    c: &Arc<dyn RoofClassifier>,
    crops: &[citymesh_core::roof_image::Crop],
) -> Vec<citymesh::roofs::classifier::Prediction> {
    let batched = c.classify(crops).unwrap();
    assert_eq!(batched.len(), 70);
    for (crop, b) in crops.iter().zip(&batched) {
        let sum: f32 = b.probabilities.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "{sum}");
        assert!(b.probabilities.iter().all(|p| (0.0..=1.0).contains(p)));
        let single = c.classify(std::slice::from_ref(crop)).unwrap()[0];
        for k in 0..3 {
            assert!((single.probabilities[k] - b.probabilities[k]).abs() < 1e-5);
        }
        assert_eq!(single.class(), b.class());
    }
    assert!(c.classify(&[]).unwrap().is_empty());
    batched
}

#[test]
fn a_crop_recropped_by_its_own_mask_keeps_its_mask() {
    let pools = pools();
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for i in 0..30u64 {
        let sample = render_sample(&pools[0], 500 + i, Palette::Training, MODEL_RULE).unwrap();
        let Some(mask) = &sample.crop.mask else {
            continue;
        };
        let path = dir.path().join(format!("{i}.png"));
        write_png(&path, &sample.crop).unwrap();
        let again = crop_image(&std::fs::read(&path).unwrap(), true, MODEL_RULE).unwrap();
        let again_mask = again.mask.expect("a mask");
        let both = mask
            .iter()
            .zip(&again_mask)
            .filter(|(a, b)| **a == 255 && **b == 255)
            .count();
        let either = mask
            .iter()
            .zip(&again_mask)
            .filter(|(a, b)| **a == 255 || **b == 255)
            .count();
        let iou = both as f64 / either as f64;
        assert!(iou > 0.85, "sample {i}: mask IoU {iou:.3}");
        checked += 1;
    }
    assert!(checked >= 10, "{checked}");
}

fn run_cli(args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .arg("classify-image")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn classify_image_reads_png_and_jpeg_of_any_size_and_prints_json_lines() {
    let pools = pools();
    let dir = tempfile::tempdir().unwrap();
    let sample = (0..10u64)
        .filter_map(|i| render_sample(&pools[0], 40 + i, Palette::Holdout, MODEL_RULE))
        .find(|s| s.crop.mask.is_some())
        .unwrap();
    let rgba = dir.path().join("crop.png");
    write_png(&rgba, &sample.crop).unwrap();
    let img = image::open(&rgba).unwrap();
    let big = dir.path().join("big.png");
    img.resize_exact(200, 200, image::imageops::FilterType::Triangle)
        .save(&big)
        .unwrap();
    let jpeg = dir.path().join("odd.jpg");
    image::DynamicImage::ImageRgb8(
        img.resize_exact(97, 131, image::imageops::FilterType::Triangle)
            .to_rgb8(),
    )
    .save(&jpeg)
    .unwrap();
    let garbage = dir.path().join("garbage.png");
    std::fs::write(&garbage, b"\x89PNG not really").unwrap();

    let out = run_cli(&[rgba.as_os_str(), big.as_os_str(), jpeg.as_os_str()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    for (line, file) in lines.iter().zip([&rgba, &big, &jpeg]) {
        assert_eq!(line["file"], file.display().to_string());
        assert_eq!(line["model_id"], model_id_of(MODEL));
        let probs: Vec<(String, f64)> = RoofClass::ALL
            .iter()
            .map(|c| {
                (
                    c.name().to_owned(),
                    line["probabilities"][c.name()].as_f64().unwrap(),
                )
            })
            .collect();
        let sum: f64 = probs.iter().map(|p| p.1).sum();
        assert!((sum - 1.0).abs() < 1e-5, "{line}");
        let best = probs.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        assert_eq!(line["class"], best.0, "{line}");
    }

    // With --footprint-mask: the PNG's alpha is used; the JPEG has none and the garbage is no
    // image: both get an error line, the run exits 1, and every file still gets its line.
    let out = run_cli(&[
        std::ffi::OsStr::new("--footprint-mask"),
        rgba.as_os_str(),
        jpeg.as_os_str(),
        garbage.as_os_str(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let lines: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0]["footprint_mask"], true);
    assert!(lines[0]["class"].is_string());
    assert!(
        lines[1]["error"].as_str().unwrap().contains("alpha"),
        "{}",
        lines[1]
    );
    assert!(
        lines[2]["error"].as_str().unwrap().contains("PNG or JPEG"),
        "{}",
        lines[2]
    );
}

#[test]
fn without_onnx_runtime_classify_image_says_how_to_install_it() {
    let out = run_cli(&[
        std::ffi::OsStr::new("--onnxruntime-lib"),
        std::ffi::OsStr::new("/nonexistent/libonnxruntime.so"),
        std::ffi::OsStr::new("x.png"),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("/nonexistent/libonnxruntime.so does not exist"),
        "{err}"
    );
    assert!(err.contains("pip install 'onnxruntime>=1.31'"), "{err}");
}

#[tokio::test]
async fn the_server_reports_its_classifier_and_serves_without_one() {
    let dem = common::dem_dir();
    let db = tempfile::tempdir().unwrap();
    // Asked for, but no runtime: a warning, and everything else serves.
    let osm = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let app = common::app_with(
        &dem,
        &db.path().join("a.sqlite"),
        &[
            "--osm",
            osm.to_str().unwrap(),
            "--roof-classifier",
            "--onnxruntime-lib",
            "/nonexistent/libonnxruntime.so",
        ],
    )
    .await;
    let health = common::get(&app, "/health").await;
    assert_eq!(health.status, 200);
    assert_eq!(health.json()["roof_classifier"], serde_json::Value::Null);
    assert_eq!(
        common::get(&app, "/tiles/16/34297/22502.glb").await.status,
        200
    );

    // Off (the default): nothing loads.
    let app = common::app_with(&dem, &db.path().join("b.sqlite"), &[]).await;
    assert_eq!(
        common::get(&app, "/health").await.json()["roof_classifier"],
        serde_json::Value::Null
    );

    // On, with the runtime from .venv: the model's id.
    let app = common::app_with(&dem, &db.path().join("c.sqlite"), &["--roof-classifier"]).await;
    assert_eq!(
        common::get(&app, "/health").await.json()["roof_classifier"],
        model_id_of(MODEL)
    );
}

//! The roof classifier on real imagery: the committed model run through citymesh's own crop path
//! (the footprint drawn as the mask) on the real Atlanta crops of `../shared/data/roofs/atlanta`,
//! as shipped and after `citymesh adapt-roofs` fits a head on the `train` split. The counts are
//! the model card's (training/roof_classifier/MODEL_CARD.md); `val` is never trained or tuned on.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

mod common;

use citymesh::classifier::labelled::{LabelledImage, evaluate, read_labels};
use citymesh::classifier::{MODEL_RULE, Passes, load_classifier};
use std::path::PathBuf;

/// Atlanta `val` crops the shipped model gets right (of 111), with the footprint mask.
const SHIPPED_VAL_CORRECT: usize = 88;
/// Atlanta `val` crops right after adapting on the `train` split with `adapt-roofs --labels`.
const ADAPTED_VAL_CORRECT: usize = 89;

fn labels_csv() -> PathBuf {
    let csv = common::data_dir().join("roofs/atlanta/labels.csv");
    assert!(
        csv.is_file(),
        "the real roof crops are missing: {} (see ../shared/data/README.md)",
        csv.display()
    );
    csv
}

fn split(name: &str) -> Vec<LabelledImage> {
    read_labels(&labels_csv())
        .unwrap()
        .into_iter()
        .filter(|r| r.split.as_deref() == Some(name))
        .collect()
}

#[test]
fn the_shipped_model_on_real_atlanta_val_crops_scores_the_model_cards_count() {
    let val = split("val");
    assert_eq!(val.len(), 111);
    assert!(val.iter().all(|r| r.footprint.is_some()));
    let classifier = load_classifier(None, None, Passes::default()).unwrap_or_else(|e| {
        panic!("{e}\n(scripts/test installs onnxruntime into .venv; run it once)")
    });
    let report = evaluate(classifier.as_ref(), &val, MODEL_RULE).unwrap();
    eprintln!(
        "shipped: {}/{} right, confusion {:?}",
        report.correct, report.count, report.confusion
    );
    assert!(report.failed.is_empty(), "{:?}", report.failed);
    assert_eq!(report.count, 111);
    assert_eq!(
        report.correct, SHIPPED_VAL_CORRECT,
        "{:?}",
        report.confusion
    );
}

fn citymesh(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_citymesh"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn a_head_adapted_on_the_train_split_scores_the_model_cards_count_on_val() {
    let csv = labels_csv();
    let csv = csv.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let head = dir.path().join("atlanta-head.json");
    let head = head.to_str().unwrap();
    let out = citymesh(&[
        "adapt-roofs",
        "--labels",
        csv,
        "--split",
        "train",
        "-o",
        head,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!("adapt-roofs: {report}");
    assert_eq!(report["examples"]["flat"], 41);
    assert_eq!(report["examples"]["gabled"], 76);
    assert_eq!(report["examples"]["hipped"], 105);
    assert_eq!(report["cross_validation"]["folds"], 5);
    let confusion = &report["cross_validation"]["confusion"];
    let total: u64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| confusion[i][j].as_u64().unwrap())
        .sum();
    assert_eq!(total, 222);

    let out = citymesh(&[
        "classify-image",
        "--labels",
        csv,
        "--split",
        "val",
        "--head",
        head,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 112, "one line per crop and a summary");
    let summary = &lines[111]["summary"];
    eprintln!("adapted on val: {summary}");
    assert_eq!(summary["count"], 111);
    assert!(
        lines[111]["model_id"].as_str().unwrap().contains("+head-"),
        "{}",
        lines[111]
    );
    assert_eq!(
        summary["correct"].as_u64().unwrap() as usize,
        ADAPTED_VAL_CORRECT
    );
}

#[test]
fn adapt_roofs_with_too_few_examples_says_so_and_writes_nothing() {
    // The first 30 rows of the train split: fewer than 20 flat roofs among them.
    let dir = tempfile::tempdir().unwrap();
    let full = std::fs::read_to_string(labels_csv()).unwrap();
    let images = common::data_dir().join("roofs/atlanta/images");
    let mut small = String::new();
    let mut lines = full.lines();
    small.push_str(lines.next().unwrap());
    small.push('\n');
    for line in lines.filter(|l| l.contains(",train,")).take(30) {
        let (file, rest) = line.split_once(',').unwrap();
        small.push_str(&format!("{},{rest}\n", images.join(file).display()));
    }
    let csv = dir.path().join("few.csv");
    std::fs::write(&csv, small).unwrap();
    let head = dir.path().join("head.json");
    let out = citymesh(&[
        "adapt-roofs",
        "--labels",
        csv.to_str().unwrap(),
        "-o",
        head.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("at least 20 per class"), "{stderr}");
    assert!(!head.exists());
}

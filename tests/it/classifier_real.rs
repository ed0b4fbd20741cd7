//! The roof classifier on real imagery: the committed model run through citymesh's own crop path
//! (the footprint drawn as the mask) on the real Atlanta crops of `../shared/data/roofs/atlanta`,
//! as shipped and after `citymesh adapt-roofs` fits a head on the `train` split. The counts are
//! the model card's (training/roof_classifier/MODEL_CARD.md); `val` is never trained or tuned on.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use citymesh::roofs::classifier::labelled::{LabelledImage, evaluate, read_labels};
use citymesh::roofs::classifier::{MODEL_RULE, Passes, load_classifier};
use std::path::PathBuf;

/// Atlanta `val` crops the shipped model gets right (of 111), with the footprint mask.
const SHIPPED_VAL_CORRECT: usize = 89;
/// Atlanta `val` crops right after adapting on the `train` split with `adapt-roofs --labels`.
const ADAPTED_VAL_CORRECT: usize = 91;

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

/// The Atlanta footprints as OSM buildings, each alone (1 km from the next, so no neighbours):
/// `train` ones tagged with their label, `val` ones untagged. Names in input order.
fn atlanta_footprints() -> (Vec<citymesh_core::osm::BuildingRecord>, Vec<String>) {
    use citymesh_core::geo::LocalFrame;
    use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
    let csv = labels_csv();
    let mut reader = csv::Reader::from_path(&csv).unwrap();
    let headers = reader.headers().unwrap().clone();
    let column = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (file, split, mpp) = (column("file"), column("split"), column("metres_per_px"));
    let rows: Vec<LabelledImage> = read_labels(&csv).unwrap();
    let frame = LocalFrame::new(-84.39, 33.75, 0.0);
    let (mx, my) = frame.metres_per_degree();
    let mut records = Vec::new();
    let mut names = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let record = record.unwrap();
        let row = rows.iter().find(|r| r.name == record[file]).unwrap();
        let metres: f64 = record[mpp].parse().unwrap();
        let (cx, cy) = (1000.0 * (i % 20) as f64, 1000.0 * (i / 20) as f64);
        let ring = |px: &Vec<[f64; 2]>| Ring {
            nodes: px[..px.len() - usize::from(px.first() == px.last())]
                .iter()
                .map(|p| RingNode {
                    id: None,
                    lon: -84.39 + (cx + p[0] * metres) / mx,
                    lat: 33.75 + (cy - p[1] * metres) / my,
                })
                .collect(),
        };
        let footprint = row.footprint.as_ref().unwrap();
        let mut tags = Tags::new();
        tags.insert("building".into(), "yes".into());
        if &record[split] == "train" {
            tags.insert("roof:shape".into(), row.label.name().into());
        }
        records.push(BuildingRecord {
            id: OsmId::Way(i as i64 + 1),
            is_part: false,
            outers: vec![ring(&footprint[0])],
            inners: footprint[1..].iter().map(ring).collect(),
            tags,
        });
        names.push(row.name.clone());
    }
    (records, names)
}

/// The roof prior learned from the `train` footprints alone (no tags, no neighbours: their outline
/// is all it knows) against the shipped model on `val`, and their product (what
/// `roofs=classified` does where a prior applies). The prior alone gets 77 of 111 (69 %, against
/// 48 % for always answering hipped), but it adds nothing to a model that already sees the
/// footprint as its mask: the product counts the outline twice and gets 85, three fewer than the
/// model alone. Where a prior knows more than the outline (tags, neighbours' shapes), the
/// product gains: `tests/it/classify_with_prior.rs`.
#[test]
fn on_atlanta_a_prior_of_outlines_alone_adds_nothing_to_the_model() {
    use citymesh_core::learn::cross_validation::argmax;
    use citymesh_core::roof_prior::{RoofPrior, combine};
    let (records, names) = atlanta_footprints();
    let refs: Vec<&citymesh_core::osm::BuildingRecord> = records.iter().collect();
    let prior = RoofPrior::fit(&refs);
    let classifier = load_classifier(None, None, Passes::default()).unwrap();
    let report = evaluate(classifier.as_ref(), &split("val"), MODEL_RULE).unwrap();
    let (mut image, mut alone, mut both) = (0, 0, 0);
    for (name, truth, p) in &report.predictions {
        let at = names.iter().position(|n| n == name).unwrap();
        let from_prior = prior.probabilities(&records[at].id).unwrap();
        let t = truth.index();
        image += usize::from(argmax(&p.probabilities) == t);
        alone += usize::from(argmax(&from_prior) == t);
        both += usize::from(argmax(&combine(p.probabilities, from_prior)) == t);
    }
    eprintln!(
        "val: image {image}, prior {alone}, combined {both}; prior {:?}",
        prior.report
    );
    assert_eq!(prior.report.tagged, 222);
    assert_eq!(prior.report.cross_validated_correct, Some(152));
    assert_eq!((image, alone, both), (SHIPPED_VAL_CORRECT, 77, 85));
}

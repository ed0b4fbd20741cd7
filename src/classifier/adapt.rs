//! `citymesh adapt-roofs`: fits a head of the roof classifier on labelled crops of the user's
//! imagery ([`super::head`]) and writes it, with its cross-validated report.

use super::head::{AdaptError, fit_head};
use super::labelled::read_labels;
use super::{MODEL_RULE, load_onnx};
use crate::cli::AdaptRoofsArgs;
use citymesh_core::roof_image::RoofClass;
use serde_json::json;

/// Fits and writes the head; prints the report as JSON. `Ok(false)` when there were too few
/// examples (the message says so and nothing is written).
pub fn run_labels(args: &AdaptRoofsArgs) -> anyhow::Result<bool> {
    let rows = read_labels(&args.labels)?;
    let rows: Vec<_> = rows
        .into_iter()
        .filter(|r| args.split.is_none() || r.split == args.split)
        .collect();
    let classifier = load_onnx(
        args.classifier.onnxruntime_lib.as_deref(),
        args.classifier.roof_model.as_deref(),
        args.classifier.roof_passes,
    )?;
    let started = std::time::Instant::now();
    let mut crops = Vec::with_capacity(rows.len());
    let mut failed = 0usize;
    for row in &rows {
        match row.crop(MODEL_RULE) {
            Ok(c) => crops.push((c, row.label)),
            Err(e) => {
                failed += 1;
                eprintln!("skipped: {e}");
            }
        }
    }
    let head = match fit_head(&classifier, &crops) {
        Ok(h) => h,
        Err(e @ AdaptError::TooFew { .. }) => {
            eprintln!("error: {e}");
            return Ok(false);
        }
        Err(e) => return Err(e.into()),
    };
    head.write(&args.out)?;
    let r = &head.report;
    println!(
        "{}",
        json!({
            "head": args.out.display().to_string(),
            "head_id": head.id(),
            "model_id": head.model_id,
            "examples": RoofClass::ALL
                .iter()
                .map(|c| (c.name().to_owned(), json!(r.examples[c.index()])))
                .collect::<serde_json::Map<_, _>>(),
            "skipped": failed,
            "cross_validation": {"folds": super::head::FOLDS, "accuracy": r.accuracy, "confusion": r.confusion},
            "shipped_head_accuracy": r.shipped_accuracy,
            "threshold": r.threshold,
            "seconds": started.elapsed().as_secs_f64(),
        })
    );
    Ok(true)
}

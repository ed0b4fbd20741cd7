//! `citymesh classify-image`: one JSON line per image file with the class probabilities.

use crate::cli::ClassifyImageArgs;
use crate::roofs::classifier::input::crop_image;
use crate::roofs::classifier::labelled::read_limited;
use crate::roofs::classifier::labelled::{evaluate, read_labels};
use crate::roofs::classifier::{MODEL_RULE, load_classifier_with_head};
use citymesh_core::roof_image::RoofClass;
use serde_json::json;

/// Classifies every file and prints a line for each; `Ok(false)` when a file failed (its line
/// says why). Loading the classifier failing is an error.
pub fn run(args: &ClassifyImageArgs) -> anyhow::Result<bool> {
    let classifier = load_classifier_with_head(
        args.classifier.onnxruntime_lib.as_deref(),
        args.classifier.roof_model.as_deref(),
        args.classifier.roof_passes,
        args.head.as_deref(),
    )?;
    if let Some(labels) = &args.labels {
        let rows: Vec<_> = read_labels(labels)?
            .into_iter()
            .filter(|r| args.split.is_none() || r.split == args.split)
            .collect();
        let report = evaluate(classifier.as_ref(), &rows, MODEL_RULE)?;
        for (name, truth, p) in &report.predictions {
            println!(
                "{}",
                json!({"file": name, "label": truth.name(), "class": p.class().name(),
                       "probabilities": p.probabilities})
            );
        }
        println!(
            "{}",
            json!({"summary": report, "model_id": classifier.model_id(), "split": args.split})
        );
        return Ok(report.failed.is_empty());
    }
    let mut all_ok = true;
    for file in &args.files {
        let name = file.display().to_string();
        let crop = read_limited(file)
            .and_then(|bytes| crop_image(&bytes, args.footprint_mask, MODEL_RULE))
            .map_err(|e| e.to_string());
        let line = match crop.and_then(|c| {
            classifier
                .classify(std::slice::from_ref(&c))
                .map_err(|e| e.to_string())
        }) {
            Ok(predictions) if predictions.len() == 1 => {
                let p = predictions[0];
                let probabilities: serde_json::Map<String, serde_json::Value> = RoofClass::ALL
                    .iter()
                    .map(|c| (c.name().to_owned(), json!(p.probabilities[c.index()])))
                    .collect();
                json!({
                    "file": name,
                    "class": p.class().name(),
                    "probabilities": probabilities,
                    "footprint_mask": args.footprint_mask,
                    "model_id": classifier.model_id(),
                })
            }
            Ok(_) => {
                all_ok = false;
                json!({"file": name, "error": "the model gave no answer"})
            }
            Err(e) => {
                all_ok = false;
                json!({"file": name, "error": e})
            }
        };
        println!("{line}");
    }
    Ok(all_ok)
}

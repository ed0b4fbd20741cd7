//! `citymesh classify-image`: one JSON line per image file with the class probabilities.

use super::input::crop_image;
use super::{MODEL_RULE, load_classifier};
use crate::cli::ClassifyImageArgs;
use citymesh_core::roof_image::RoofClass;
use serde_json::json;

/// Largest image file read (bytes).
const MAX_FILE_BYTES: u64 = 64 << 20;

/// Classifies every file and prints a line for each; `Ok(false)` when a file failed (its line
/// says why). Loading the classifier failing is an error.
pub fn run(args: &ClassifyImageArgs) -> anyhow::Result<bool> {
    let classifier = load_classifier(
        args.classifier.onnxruntime_lib.as_deref(),
        args.classifier.roof_model.as_deref(),
        args.classifier.roof_passes,
    )?;
    let mut all_ok = true;
    for file in &args.files {
        let name = file.display().to_string();
        let crop = read_limited(file).and_then(|bytes| {
            crop_image(&bytes, args.footprint_mask, MODEL_RULE).map_err(|e| e.to_string())
        });
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

fn read_limited(path: &std::path::Path) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(format!("larger than {} MiB", MAX_FILE_BYTES >> 20));
    }
    Ok(bytes)
}

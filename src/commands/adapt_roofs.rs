//! `citymesh adapt-roofs`: fits a head of the roof classifier ([`crate::roofs::classifier::head`]) on labelled crops
//! of the user's imagery, or on the buildings of OSM files whose roofs are tagged, cropped from an
//! imagery service as the server crops them; writes it, with its cross-validated report.

use super::load_classifier;
use crate::cli::AdaptRoofsArgs;
use crate::roofs::classifier::head::{AdaptError, fit_head};
use crate::roofs::classifier::labelled::read_labels;
use crate::roofs::classifier::{MODEL_RULE, RoofClassifier as _};
use crate::roofs::jobs::adapt::{
    AdaptationStore, Lease, Progress, class_counts, fit_on_imagery, tagged_examples,
};
use citymesh_core::roof_image::RoofClass;
use serde_json::json;

/// Fits and writes the head; prints the report as JSON. `Ok(false)` when there were too few
/// examples (the message says so and nothing is written).
pub fn run_labels(args: &AdaptRoofsArgs) -> anyhow::Result<bool> {
    let labels = args
        .labels
        .as_deref()
        .ok_or_else(|| anyhow::anyhow!("--labels is required"))?;
    let rows = read_labels(labels)?;
    let rows: Vec<_> = rows
        .into_iter()
        .filter(|r| args.split.is_none() || r.split == args.split)
        .collect();
    let classifier = load_classifier(&args.classifier)?;
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
    let (crops, classes): (Vec<_>, Vec<_>) = crops.into_iter().unzip();
    let head = match fit_head(&classifier, &crops, &classes, &|| false) {
        Ok(h) => h,
        Err(e @ AdaptError::TooFew { .. }) => {
            eprintln!("error: {e}");
            return Ok(false);
        }
        Err(e) => return Err(e.into()),
    };
    print_report(args, &head, failed, started)?;
    Ok(true)
}

/// Fits a head on the tagged buildings of `--osm` files, cropped from `--imagery-url`; writes it
/// to `--out` and stores it in `--cache-db` for that imagery. `Ok(false)` when too few examples
/// could be cropped.
pub async fn run_osm(args: &AdaptRoofsArgs) -> anyhow::Result<bool> {
    let (bbox, records) = super::classify::read_area(&args.osm, args.bbox.as_deref())?;
    let examples = tagged_examples(&records, bbox.as_ref());
    let classifier = load_classifier(&args.classifier)?;
    let db = crate::db::Database::Sqlite(crate::db::open(&args.cache_db).await?);
    let imagery = args.imagery.open(&db, None).await?.ok_or_else(|| {
        anyhow::anyhow!("--imagery-url is required with --osm: the imagery to adapt to")
    })?;
    let counts = class_counts(&examples);
    let store = AdaptationStore::new(db);
    let id = crate::roofs::jobs::random_token()?;
    let area = bbox.map_or_else(|| "files".to_owned(), |b| b.to_string());
    store
        .create(
            &id,
            &area,
            &imagery.spec().id,
            classifier.model_id(),
            counts,
            &Lease {
                owner: "adapt-roofs".to_owned(),
                duration: std::time::Duration::from_secs(86_400),
            },
        )
        .await?;
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(examples.len() as u64)
    };
    let started = std::time::Instant::now();
    let never = tokio_util::sync::CancellationToken::new();
    let outcome = fit_on_imagery(
        &classifier,
        &imagery,
        &examples,
        &Progress::Bar(&bar),
        &never,
    )
    .await;
    bar.finish_and_clear();
    // The server uses the stored head only when it beats the shipped one, as it would have
    // fitted it itself; the file is written either way.
    let better = outcome
        .as_ref()
        .is_ok_and(|h| h.report.accuracy > h.report.shipped_accuracy);
    store.record(&id, &outcome, better).await?;
    if outcome.is_ok() && !better {
        eprintln!(
            "note: the head does not beat the shipped one out of fold: it is stored as \
             not_better and a server does not use it"
        );
    }
    match outcome {
        Ok(head) => {
            print_report(args, &head, 0, started)?;
            Ok(true)
        }
        Err(e) => {
            eprintln!("error: {e}");
            Ok(false)
        }
    }
}

fn print_report(
    args: &AdaptRoofsArgs,
    head: &crate::roofs::classifier::head::RoofHead,
    failed: usize,
    started: std::time::Instant,
) -> anyhow::Result<()> {
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
            "cross_validation": {"folds": crate::roofs::classifier::head::FOLDS, "accuracy": r.accuracy, "confusion": r.confusion},
            "shipped_head_accuracy": r.shipped_accuracy,
            "threshold": r.threshold,
            "seconds": started.elapsed().as_secs_f64(),
        })
    );
    Ok(())
}

//! `citymesh classify`: the roofs of OSM buildings from an imagery service, as the server's jobs
//! run them (same queue, same database), in the foreground with a progress bar.

use super::load_classifier;
use crate::cli::ClassifyArgs;
use crate::roofs::classifier::{Prediction, RoofClassifier};
use crate::roofs::jobs::worker::{WorkerConfig, run_round};
use crate::roofs::jobs::{JobQueue, Selection, StoredPrediction, footprint_hash, jobs_in_box};
use crate::source::read_osm_file;
use citymesh_core::building::roof::RoofShape;
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::{BuildingRecord, read_buildings};
use citymesh_core::roof_image::RoofClass;
use serde_json::json;
use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

/// The `--bbox` as given and every building of the `--osm` files.
pub(super) fn read_area(
    osm: &[std::path::PathBuf],
    bbox: Option<&str>,
) -> anyhow::Result<(Option<GeoBbox>, Vec<BuildingRecord>)> {
    let bbox: Option<GeoBbox> = bbox
        .map(str::parse)
        .transpose()
        .map_err(|e| anyhow::anyhow!("--bbox: {e}"))?;
    let mut records = Vec::new();
    for path in osm {
        let bytes = read_osm_file(path)?;
        let osm = read_buildings(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        records.extend(osm.buildings);
    }
    Ok((bbox, records))
}

/// Runs the command; returns the summary it prints.
pub async fn run(args: &ClassifyArgs) -> anyhow::Result<String> {
    let (bbox, records) = read_area(&args.osm, args.bbox.as_deref())?;
    let classifier: Arc<dyn RoofClassifier> = load_classifier(&args.classifier)?;
    let db = crate::db::Database::Sqlite(crate::db::open(&args.cache_db).await?);
    let imagery = args.imagery.open(&db, None).await?.ok_or_else(|| {
        anyhow::anyhow!("--imagery-url is required: the imagery to classify from")
    })?;
    let queue = JobQueue::new(&db);
    let selection = if args.all {
        Selection::All
    } else {
        Selection::Untagged
    };
    // The buildings the box holds, by the rule `POST /classify` uses.
    let (jobs, skipped) = jobs_in_box(&records, bbox.as_ref(), selection, None);
    let tags: HashMap<String, Option<String>> = records
        .iter()
        .map(|r| (r.id.to_string(), r.tags.get("roof:shape").cloned()))
        .collect();
    let area = bbox.map_or_else(|| "files".to_owned(), |b| b.to_string());
    let (batch, counts) = queue
        .enqueue(
            &area,
            &imagery.spec().id,
            classifier.model_id(),
            &jobs,
            skipped,
        )
        .await?;
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(jobs.len() as u64)
    };
    let started = std::time::Instant::now();
    let config = WorkerConfig::default();
    loop {
        let round = run_round(&queue, &imagery, &classifier, config, &|_, _, _| {}).await?;
        let progress = queue
            .progress(&batch)
            .await?
            .ok_or_else(|| anyhow::anyhow!("batch {batch} vanished"))?;
        let ended = progress.jobs["done"] + progress.jobs["failed"] + progress.jobs["cancelled"];
        bar.set_position(ended + counts.already);
        if progress.finished || round.is_none() {
            break;
        }
    }
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let progress = queue
        .progress(&batch)
        .await?
        .ok_or_else(|| anyhow::anyhow!("batch {batch} vanished"))?;

    // The predictions of this batch's buildings (made now or before, for the same inputs).
    let wanted: HashMap<(String, String), &Vec<[f64; 2]>> = jobs
        .iter()
        .map(|j| {
            (
                (j.osm_id.clone(), footprint_hash(&j.footprint)),
                &j.footprint,
            )
        })
        .collect();
    // Each prediction with its building's roof:shape tag.
    let mut results: Vec<(Option<String>, StoredPrediction)> = Vec::new();
    if let Some(area) = area_of(&jobs) {
        for p in queue.predictions(&area, u32::MAX).await? {
            if p.imagery_id == imagery.spec().id
                && p.model_id == classifier.model_id()
                && wanted.contains_key(&(p.osm_id.clone(), p.footprint_hash.clone()))
            {
                let tag = tags.get(&p.osm_id).cloned().flatten();
                results.push((tag, p));
            }
        }
    }
    let features: Vec<serde_json::Value> = results
        .iter()
        .map(|(tag, stored)| {
            let (id, p) = (&stored.osm_id, &stored.prediction);
            let mut ring = stored.footprint.clone();
            if let Some(&first) = ring.first() {
                ring.push(first);
            }
            json!({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": [ring]},
                "properties": {
                    "osm_id": id,
                    "roof_shape_tag": tag,
                    "class": p.class().name(),
                    "probabilities": RoofClass::ALL.iter().map(|c| (c.name(), p.probabilities[c.index()])).collect::<BTreeMap<_, _>>(),
                    "imagery": imagery.spec().id,
                    "imagery_attribution": imagery.spec().attribution,
                    "model_id": classifier.model_id(),
                }
            })
        })
        .collect();
    let collection = json!({"type": "FeatureCollection", "features": features});
    std::fs::write(&args.out, serde_json::to_vec_pretty(&collection)?)?;
    let pairs: Vec<(Option<String>, Prediction)> = results
        .iter()
        .map(|(t, p)| (t.clone(), p.prediction))
        .collect();
    Ok(format!(
        "batch {batch}: {} jobs queued, {} already queued or done, skipped {:?}; jobs {:?}; \
         {} predictions in {seconds:.1} s; wrote {}\n{}",
        counts.queued,
        counts.already,
        counts.skipped,
        progress.jobs,
        results.len(),
        args.out.display(),
        agreement(&pairs)
    ))
}

/// The box around every job's footprint.
fn area_of(jobs: &[crate::roofs::jobs::NewJob]) -> Option<GeoBbox> {
    let [w, s, e, n] = crate::roofs::jobs::ring_bounds(jobs.iter().flat_map(|j| &j.footprint))?;
    GeoBbox::new(w, s, e, n).ok()
}

/// How predictions agree with the tags that name one of the three classes.
pub fn agreement(results: &[(Option<String>, Prediction)]) -> String {
    let mut confusion = [[0usize; 3]; 3];
    for (tag, p) in results {
        if let Some(t) = tag
            .as_deref()
            .and_then(RoofShape::from_tag)
            .and_then(RoofClass::of_shape)
        {
            confusion[t.index()][p.class().index()] += 1;
        }
    }
    let compared: usize = confusion.iter().flatten().sum();
    if compared == 0 {
        return "no tagged building to compare with".into();
    }
    let agree: usize = (0..3).map(|i| confusion[i][i]).sum();
    format!(
        "agreement with roof:shape tags: {agree}/{compared} = {:.1} %; confusion (rows: tag \
         flat, gabled, hipped; columns: predicted): {confusion:?}",
        100.0 * agree as f64 / compared as f64
    )
}

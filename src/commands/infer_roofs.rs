//! `citymesh infer-roofs`: the roof prior of OSM files, written as GeoJSON.

use crate::cli::InferRoofsArgs;
use crate::roofs::prior::{describe, prediction_properties};
use crate::source::read_osm_file;
use anyhow::Context;
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::{BuildingRecord, read_buildings};
use citymesh_core::roof_prior::RoofPrior;
use serde_json::json;
use std::collections::HashSet;

/// Reads the files, fits the prior on all their tagged buildings, writes every untagged
/// building (in the box, if given) with its prediction, and returns the report as text.
pub fn infer_roofs(args: &InferRoofsArgs) -> anyhow::Result<String> {
    let bbox = crate::cli::bbox_arg(args.bbox.as_ref())?;
    let mut records: Vec<BuildingRecord> = Vec::new();
    let mut seen = HashSet::new();
    for path in &args.osm {
        let bytes = read_osm_file(path)?;
        let osm = read_buildings(&bytes).with_context(|| format!("reading {}", path.display()))?;
        records.extend(osm.buildings.into_iter().filter(|r| seen.insert(r.id)));
    }
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let prior = RoofPrior::fit(&refs);
    let features: Vec<serde_json::Value> = records
        .iter()
        .filter(|r| prior.probabilities(&r.id).is_some())
        .filter(|r| bbox.is_none_or(|b| touches(r, &b)))
        .map(|r| {
            let rings: Vec<Vec<[f64; 2]>> = r
                .outers
                .iter()
                .take(1)
                .chain(&r.inners)
                .map(|ring| {
                    let mut pts: Vec<[f64; 2]> =
                        ring.nodes.iter().map(|n| [n.lon, n.lat]).collect();
                    if let Some(&first) = pts.first() {
                        pts.push(first);
                    }
                    pts
                })
                .collect();
            let mut properties = prediction_properties(&prior, r);
            properties.insert("osm_id".into(), json!(r.id.to_string()));
            properties.insert(
                "building".into(),
                json!(r.tags.get("building").map_or("yes", String::as_str)),
            );
            json!({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": rings},
                "properties": properties,
            })
        })
        .collect();
    let written = features.len();
    let collection = json!({
        "type": "FeatureCollection",
        "properties": {"roof_prior": prior.report},
        "features": features,
    });
    std::fs::write(&args.out, serde_json::to_vec_pretty(&collection)?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    Ok(format!(
        "{}\nwrote {written} untagged buildings to {}",
        describe(&prior.report),
        args.out.display()
    ))
}

fn touches(r: &BuildingRecord, b: &GeoBbox) -> bool {
    r.outers.iter().flat_map(|o| &o.nodes).any(|n| {
        n.lon >= b.min_lon() && n.lon <= b.max_lon() && n.lat >= b.min_lat() && n.lat <= b.max_lat()
    })
}

//! `citymesh scene`: one scene from OSM and SRTM files into a GLB file, as a batch command (what
//! OSM2World's and ilu's command lines do), with the figures `/scene/stats` gives as JSON.

use crate::cli::SceneArgs;
use crate::dem::DemStore;
use crate::routes::scene_stats::BuildingFigures;
use crate::source::read_osm_file;
use anyhow::Context;
use citymesh_core::building::cluster::records_extent;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::GeoBbox;
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::SceneArea;
use serde_json::json;
use std::time::Instant;

/// What `citymesh scene` made.
#[derive(Debug, Clone)]
pub struct SceneReport {
    pub buildings: usize,
    pub skipped: usize,
    pub bytes: usize,
    pub generation_ms: f64,
}

/// Reads the files, generates the scene and writes the GLB (and the figures, with `--stats`).
/// Blocking: the whole command is one scene.
pub fn export_scene(args: &SceneArgs) -> anyhow::Result<SceneReport> {
    let started = Instant::now();
    let mut records = Vec::new();
    let (mut load_skips, mut repaired) = (Vec::new(), Vec::new());
    for path in &args.osm {
        let bytes = read_osm_file(path)?;
        let osm = read_buildings(&bytes).with_context(|| format!("reading {}", path.display()))?;
        load_skips.extend(osm.skipped);
        repaired.extend(osm.repaired);
        records.extend(osm.buildings);
    }
    let given = crate::cli::bbox_arg(args.bbox.as_ref())?;
    let dem = DemStore::open(&args.dem_dir, 1 << 30);
    // The ground under the buildings (and a margin around a given box, which buildings cut at
    // its border may reach into) loads on a second thread while the building set is indexed;
    // only the rows of the SRTM files it covers are read.
    let ground_area = given
        .map(|b| b.grown_by_metres(GROUND_MARGIN_M))
        .or_else(|| records_extent(&records));
    let (set, ground) = std::thread::scope(|s| {
        let ground = ground_area.map(|area| {
            let dem = &dem;
            s.spawn(move || (area, dem.read_for(&area)))
        });
        let set = BuildingSet::new(records);
        (set, ground.and_then(|g| g.join().ok()))
    });
    // With a box: the scene of `/scene?bbox=`, buildings cut at its border. Without: every
    // building whole, on the ground of their extent.
    let area = match given {
        Some(bbox) => SceneArea::Bbox(bbox),
        None => SceneArea::Given(
            set.extent()
                .context("the OSM files hold no building: nothing to make")?,
        ),
    };
    let request = area
        .request(&set)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .with_encoding(args.encoding.into())
        .with_heights(args.height_base.into())
        .with_roof_method(args.roof_method.into())
        // One scene and nothing else to do: every core may build groups.
        .with_workers(std::thread::available_parallelism().map_or(1, usize::from));
    let terrain = request.terrain_bbox();
    let lookup = match ground {
        Some((area, lookup)) if covers(&area, &terrain) => lookup,
        _ => dem.read_for(&terrain),
    };
    if !lookup.missing.is_empty() {
        eprintln!(
            "warning: SRTM files missing in {}: {}; the ground there is flat at 0 m",
            args.dem_dir.display(),
            lookup.missing.join(", ")
        );
    }
    let generating = Instant::now();
    let mut output = request.generate(&lookup.model);
    let generation_ms = generating.elapsed().as_secs_f64() * 1000.0;
    // What the files had but could not be built, and what was built with less, as the server
    // reports them.
    let used: std::collections::HashSet<_> = request
        .groups
        .iter()
        .flat_map(|c| set.cluster_records(c))
        .map(|r| r.id)
        .collect();
    output
        .buildings
        .note_reading(&load_skips, &repaired, &|id| used.contains(&id));
    warn_about(&output.buildings);
    std::fs::write(&args.out, &output.glb.bytes)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let report = SceneReport {
        buildings: output.buildings.generated,
        skipped: output.buildings.total_skipped(),
        bytes: output.glb.bytes.len(),
        generation_ms,
    };
    if let Some(path) = &args.stats {
        let stats = json!({
            "encoding": args.encoding,
            "bytes": report.bytes,
            "vertices": output.glb.vertices,
            "triangles": output.glb.triangles,
            "generation_ms": generation_ms,
            "total_ms": started.elapsed().as_secs_f64() * 1000.0,
            "ground": {
                "cells": output.ground.cells,
                "void_cells": output.ground.void_cells,
                "missing_samples": output.ground.missing_samples,
                "triangles": output.ground.triangles,
            },
            "missing_dem": lookup.missing,
            // The same figures as /scene/stats gives.
            "buildings": BuildingFigures::of(&output.buildings, 0, 0),
            "skipped_when_reading": load_skips.len(),
            "flat_roof_percent": output.buildings.flat_roof_percent(),
        });
        std::fs::write(path, serde_json::to_vec_pretty(&stats)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    // The process ends with this command: the system takes the building set, the terrain and
    // the mesh back at once, faster than freeing them piece by piece (a tenth of the run).
    std::mem::forget((set, lookup, output));
    Ok(report)
}

/// Says on the console what was not drawn as the data describes, with the first ids of each kind
/// (the `--stats` file lists them all).
fn warn_about(b: &citymesh_core::building::BuildingStats) {
    let first = |ids: Vec<String>| {
        let more = ids.len().saturating_sub(5);
        let mut shown = ids.into_iter().take(5).collect::<Vec<_>>().join(", ");
        if more > 0 {
            shown.push_str(&format!(" and {more} more"));
        }
        shown
    };
    let lists = [
        (
            "skipped",
            b.skipped_ids
                .iter()
                .map(|(id, why)| format!("{id} ({why})"))
                .collect::<Vec<_>>(),
        ),
        (
            "drawn with less than the data describes",
            b.repaired_ids
                .iter()
                .map(|(id, what)| format!("{id} ({what})"))
                .collect(),
        ),
        (
            "with a roof:shape citymesh does not draw (drawn flat)",
            b.unsupported_shape_ids
                .iter()
                .map(|(id, shape)| format!("{id} ({shape})"))
                .collect(),
        ),
        (
            "missing part of their outline",
            b.area_lost_ids
                .iter()
                .map(|(id, m2)| format!("{id} ({m2} m²)"))
                .collect(),
        ),
    ];
    for (what, ids) in lists {
        if !ids.is_empty() {
            eprintln!("warning: {} buildings {what}: {}", ids.len(), first(ids));
        }
    }
}

/// How far around a given box the ground is read ahead, metres: buildings cut at the box's
/// border reach this far in all but odd cases (then the ground is read again).
const GROUND_MARGIN_M: f64 = 300.0;

/// Whether `outer` holds all of `inner`.
fn covers(outer: &GeoBbox, inner: &GeoBbox) -> bool {
    outer.min_lon() <= inner.min_lon()
        && outer.min_lat() <= inner.min_lat()
        && outer.max_lon() >= inner.max_lon()
        && outer.max_lat() >= inner.max_lat()
}

//! OSM files into the data-tile store, so the server can run fully offline. Each building is
//! stored with every data tile its outline overlaps, in the same Overpass JSON layout an upstream
//! answer has; the report lists the areas whose data changed, for the caller to drop what was
//! generated from them (`crate::commands::import`).

use super::data_tile::{DATA_ZOOM, affected_area};
use super::store::OsmTileStore;
use crate::source::read_osm_file;
use anyhow::Context;
use citymesh_core::building::cluster::record_bounds;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, read_buildings, write_overpass_json};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;

/// What an import did.
#[derive(Debug, Default, PartialEq)]
pub struct ImportReport {
    pub buildings: usize,
    pub skipped: usize,
    /// The skipped buildings by id, with why (`too_large`, `missing_nodes`, ...).
    pub skips: Vec<(String, &'static str)>,
    pub data_tiles: usize,
    pub changed_data_tiles: usize,
    /// The areas whose served content may have used the changed data tiles.
    pub changed_areas: Vec<GeoBbox>,
    /// Generated tiles dropped from the cache (filled in by the caller that drops them).
    pub tiles_invalidated: u64,
}

fn bar(len: u64, what: &str, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    let style = ProgressStyle::with_template(&format!(
        "{{spinner}} {what} [{{bar:30}}] {{pos}}/{{len}} ({{elapsed}})"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar
}

/// Imports the files into `store`. `quiet` hides the progress bars.
pub async fn import_files(
    files: &[PathBuf],
    store: &OsmTileStore,
    quiet: bool,
) -> anyhow::Result<ImportReport> {
    anyhow::ensure!(!files.is_empty(), "name at least one OSM file to import");
    let mut report = ImportReport::default();
    let mut records: Vec<BuildingRecord> = Vec::new();
    let mut seen = HashSet::new();
    let reading = bar(files.len() as u64, "reading", quiet);
    for path in files {
        reading.set_message(path.display().to_string());
        let path = path.clone();
        let osm = tokio::task::spawn_blocking(move || -> anyhow::Result<_> {
            let bytes = read_osm_file(&path)?;
            read_buildings(&bytes).with_context(|| {
                format!(
                    "{}: give OSM PBF, OSM XML or Overpass JSON, optionally .gz",
                    path.display()
                )
            })
        })
        .await??;
        report.skipped += osm.skipped.len();
        report.skips.extend(
            osm.skipped
                .iter()
                .map(|s| (s.id.to_string(), s.reason.name())),
        );
        for b in osm.buildings {
            if seen.insert(b.id) {
                records.push(b);
            }
        }
        reading.inc(1);
    }
    reading.finish_and_clear();
    report.buildings = records.len();

    // Every data tile a building's outline overlaps.
    let mut by_tile: BTreeMap<TileCoord, Vec<usize>> = BTreeMap::new();
    for (i, r) in records.iter().enumerate() {
        let [x0, y0, x1, y1] = record_bounds(r);
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            continue;
        }
        let nw = TileCoord::containing(DATA_ZOOM, x0, y1);
        let se = TileCoord::containing(DATA_ZOOM, x1, y0);
        for x in nw.x..=se.x {
            for y in nw.y..=se.y {
                by_tile
                    .entry(TileCoord { z: DATA_ZOOM, x, y })
                    .or_default()
                    .push(i);
            }
        }
    }
    report.data_tiles = by_tile.len();
    let writing = bar(by_tile.len() as u64, "storing data tiles", quiet);
    // One transaction: an import that is interrupted (or fails) leaves the store as it was.
    let mut writer = store.import_writer().await?;
    for (t, members) in &by_tile {
        let refs: Vec<&BuildingRecord> = members.iter().map(|&i| &records[i]).collect();
        let body = write_overpass_json(&refs);
        if writer.put(t, &body).await? {
            report.changed_data_tiles += 1;
            report.changed_areas.push(affected_area(t));
        }
        writing.inc(1);
    }
    writer.commit().await?;
    writing.finish_and_clear();
    Ok(report)
}

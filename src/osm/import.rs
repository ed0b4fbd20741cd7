//! `citymesh import FILE...`: OSM files into the data-tile store, so the server can run fully
//! offline. Each building is stored with every data tile its outline overlaps, in the same
//! Overpass JSON layout an upstream answer has; the generated tiles over each changed data tile
//! are dropped from the tile cache. Run it while the server is stopped, or restart the server
//! after it: a running server keeps the data it already parsed in memory.

use super::data_tile::{DATA_ZOOM, affected_area};
use super::files::read_osm_file;
use super::store::{DataSource, OsmTileStore};
use crate::db::{self, TileStore};
use crate::tile_cache::tile_ranges;
use anyhow::Context;
use citymesh_core::building::cluster::record_bounds;
use citymesh_core::geo::{MAX_ZOOM, TileCoord};
use citymesh_core::osm::{BuildingRecord, read_buildings, write_overpass_json};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;

/// What an import did.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct ImportReport {
    pub buildings: usize,
    pub skipped: usize,
    pub data_tiles: usize,
    pub changed_data_tiles: usize,
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

/// Imports the files into the database at `cache_db`. `quiet` hides the progress bars.
pub async fn import(
    files: &[PathBuf],
    cache_db: &str,
    quiet: bool,
) -> anyhow::Result<ImportReport> {
    anyhow::ensure!(!files.is_empty(), "name at least one OSM file to import");
    let pool = db::open(cache_db)
        .await
        .with_context(|| format!("opening the cache database {cache_db}"))?;
    let (store, tiles) = (OsmTileStore::new(pool.clone()), TileStore::new(pool));
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
    for (t, members) in &by_tile {
        let refs: Vec<&BuildingRecord> = members.iter().map(|&i| &records[i]).collect();
        let body = write_overpass_json(&refs);
        if store.put(t, &body, DataSource::Import).await? {
            report.changed_data_tiles += 1;
            report.tiles_invalidated += tiles
                .delete_ranges(&tile_ranges(&affected_area(t), (0, MAX_ZOOM)))
                .await?;
        }
        writing.inc(1);
    }
    writing.finish_and_clear();
    Ok(report)
}

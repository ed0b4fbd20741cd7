//! OSM files into the data-tile store, so the server can run fully offline, in memory that does
//! not grow with the files (a budget, `--memory-mb`). Each building is stored, packed
//! (`citymesh_core::osm::pack`), with every data tile its outline overlaps; the report lists the
//! areas whose data changed, for the caller to drop what was generated from them
//! (`crate::commands::import`).
//!
//! A PBF file is read as a stream ([`pbf_stream`]: node locations in an on-disk
//! [`node_index`], blocks decoded on every core); other formats are read whole. Records go to
//! temporary files by data tile ([`spill`]) and are grouped into data tiles at the end, each
//! written in the one transaction of the import: an import that fails or is interrupted leaves
//! the store as it was.
//!
//! How the budget is spent: a quarter on the threads' caches of node blocks, a quarter on the
//! records of one spill bucket while it is grouped; the rest is buffers, blocks being decoded
//! and the building multipolygons with their member ways (kept until the end of each file: a
//! few bytes per node of each, the one part that grows with the input, with the number of
//! multipolygon buildings).

mod node_index;
mod pbf_stream;
mod spill;

use super::data_tile::{DATA_ZOOM, affected_area};
use super::store::OsmTileStore;
use crate::source::read_osm_file;
use anyhow::Context;
use citymesh_core::building::cluster::record_bounds;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{
    BuildingRecord, MemberWays, OsmBuildings, OsmFormat, OsmId, pack_parts, read_buildings, unpack,
};
use indicatif::{ProgressBar, ProgressStyle};
use pbf_stream::{PbfError, StreamLimits};
use spill::{Spilled, TileSpill};
use std::collections::HashSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The memory budget when none is given (`--memory-mb`).
pub const DEFAULT_MEMORY_MB: u64 = 1024;
/// The smallest budget taken.
pub const MIN_MEMORY_MB: u64 = 16;
/// Skipped buildings listed by id in the report (all are counted).
const MAX_LISTED_SKIPS: usize = 10_000;
/// Packed data tiles in flight between grouping and the database.
const TILES_IN_FLIGHT: usize = 64;
/// Data tiles written at once (PostgreSQL: one round trip), unless they hold more than a
/// sixteenth of the budget first.
const WRITE_BATCH: usize = 256;

/// How an import may use the machine.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// Bytes of memory the import should stay within (besides the program itself).
    pub memory_bytes: u64,
    /// Where temporary files go (node locations: 16 bytes per node of the file; records on
    /// their way to their data tiles); the system's temporary directory when `None`.
    pub temp_dir: Option<PathBuf>,
    /// No progress bars.
    pub quiet: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            memory_bytes: DEFAULT_MEMORY_MB << 20,
            temp_dir: None,
            quiet: false,
        }
    }
}

/// What an import did.
#[derive(Debug, Default, PartialEq)]
pub struct ImportReport {
    pub buildings: usize,
    pub skipped: usize,
    /// The skipped buildings by id, with why (`too_large`, `missing_nodes`, ...): the first
    /// 10,000.
    pub skips: Vec<(String, &'static str)>,
    pub data_tiles: usize,
    pub changed_data_tiles: usize,
    /// The areas whose served content may have used the changed data tiles.
    pub changed_areas: Vec<GeoBbox>,
    /// Generated tiles dropped from the cache (filled in by the caller that drops them).
    pub tiles_invalidated: u64,
    /// Nodes, ways and relations read from PBF files.
    pub nodes: u64,
    pub ways: u64,
    pub relations: u64,
    /// Bytes of the packed data tiles written.
    pub stored_bytes: u64,
    /// Seconds the import took.
    pub seconds: f64,
}

fn bar(len: u64, what: &str, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    let style = ProgressStyle::with_template(&format!(
        "{{spinner}} {what} [{{bar:30}}] {{percent:>3}}% {{msg}} ({{elapsed}}, {{eta}} left)"
    ))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar
}

/// Building records packed for the spill, each with every data tile its outline overlaps
/// (made on the thread that read them).
struct Prepared {
    /// Data tile, whether it counts the building, the packed record.
    entries: Vec<(TileCoord, bool, std::sync::Arc<[u8]>)>,
    skipped: Vec<citymesh_core::osm::Skipped>,
    records: u64,
}

fn prepare(osm: OsmBuildings) -> Prepared {
    let mut entries = Vec::with_capacity(osm.buildings.len());
    let mut records = 0;
    for r in &osm.buildings {
        let [x0, y0, x1, y1] = record_bounds(r);
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            continue;
        }
        let nw = TileCoord::containing(DATA_ZOOM, x0, y1);
        let se = TileCoord::containing(DATA_ZOOM, x1, y0);
        let members = member_ways_of(&osm.member_ways, r.id);
        let packed: std::sync::Arc<[u8]> = pack_parts(&[r], &[], &[], members.as_slice()).into();
        for x in nw.x..=se.x {
            for y in nw.y..=se.y {
                let home = x == nw.x && y == nw.y;
                entries.push((TileCoord { z: DATA_ZOOM, x, y }, home, packed.clone()));
            }
        }
        records += 1;
    }
    Prepared {
        entries,
        skipped: osm.skipped,
        records,
    }
}

/// The member ways of `id` when it is a multipolygon (`member_ways` sorted by relation).
fn member_ways_of(member_ways: &[MemberWays], id: OsmId) -> Option<&MemberWays> {
    let OsmId::Relation(relation) = id else {
        return None;
    };
    member_ways
        .binary_search_by_key(&relation, |m| m.relation)
        .ok()
        .map(|i| &member_ways[i])
}

/// Building records into the spill.
struct Spiller {
    spill: TileSpill,
    report: ImportReport,
    /// Records spilled (a building in two files counts twice here, once in the report).
    records: u64,
}

impl Spiller {
    fn add(&mut self, p: Prepared) -> Result<(), spill::SpillError> {
        self.report.skipped += p.skipped.len();
        let room = MAX_LISTED_SKIPS.saturating_sub(self.report.skips.len());
        self.report.skips.extend(
            p.skipped
                .iter()
                .take(room)
                .map(|s| (s.id.to_string(), s.reason.name())),
        );
        for (t, home, bytes) in &p.entries {
            self.spill.push(t, *home, bytes)?;
        }
        self.records += p.records;
        Ok(())
    }
}

/// Whether the file is an uncompressed OSM PBF file (read as a stream).
fn is_pbf(path: &Path) -> std::io::Result<bool> {
    let mut head = Vec::new();
    std::fs::File::open(path)?.take(64).read_to_end(&mut head)?;
    Ok(OsmFormat::sniff(&head) == Some(OsmFormat::Pbf))
}

/// Reads every file into the spill.
fn read_files(
    files: &[PathBuf],
    temp_dir: &Path,
    options: &ImportOptions,
) -> anyhow::Result<Spiller> {
    let mut s = Spiller {
        spill: TileSpill::create(temp_dir)?,
        report: ImportReport::default(),
        records: 0,
    };
    let threads = std::thread::available_parallelism().map_or(2, usize::from);
    let limits = StreamLimits {
        threads,
        cache_bytes: usize::try_from(options.memory_bytes / 4 / threads as u64)
            .unwrap_or(usize::MAX),
    };
    for path in files {
        let name = path.display().to_string();
        let size = std::fs::metadata(path)
            .with_context(|| format!("{name}: cannot read it"))?
            .len();
        if is_pbf(path).with_context(|| format!("{name}: cannot read it"))? {
            let reading = bar(size, &name, options.quiet);
            let started = Instant::now();
            let before = s.records;
            let counts = {
                let progress = |at: u64| reading.set_position(at);
                let mut each = |p: Prepared| -> Result<(), PbfError> {
                    s.add(p).map_err(|e| PbfError::Records(e.to_string()))?;
                    let done = s.records - before;
                    let rate = done as f64 / started.elapsed().as_secs_f64().max(1e-3);
                    reading.set_message(format!("{done} buildings, {rate:.0}/s"));
                    Ok(())
                };
                pbf_stream::stream(path, temp_dir, &limits, &progress, &prepare, &mut each)
                    .with_context(|| format!("{name}: an OSM PBF file"))?
            };
            reading.finish_and_clear();
            s.report.nodes += counts.nodes;
            s.report.ways += counts.ways;
            s.report.relations += counts.relations;
            tracing::debug!(file = %name, node_reads = counts.node_reads, "node index blocks read");
        } else {
            // Read whole: about ten times its size in memory.
            anyhow::ensure!(
                size.saturating_mul(10) <= options.memory_bytes,
                "{name}: {size} bytes of OSM XML or JSON are read whole, more than the memory \
                 budget allows; convert it to PBF (`osmium cat {name} -o file.osm.pbf`), which \
                 is read as a stream, or raise --memory-mb"
            );
            let bytes = read_osm_file(path)?;
            let osm = read_buildings(&bytes).with_context(|| {
                format!("{name}: give OSM PBF, OSM XML or Overpass JSON, optionally .gz")
            })?;
            drop(bytes);
            s.add(prepare(osm))?;
        }
    }
    Ok(s)
}

/// The elements a data tile's buildings are made from (for the replication index).
type Elements = Vec<(super::store::ElementKind, i64)>;

/// One data tile's records from the spill: one per building (the first file's, when files
/// repeat one), by id, packed; and how many of them this tile counts.
fn data_tile_of(records: Vec<Spilled>) -> anyhow::Result<(Vec<u8>, usize, Elements)> {
    let mut seen = HashSet::new();
    let mut kept: Vec<BuildingRecord> = Vec::with_capacity(records.len());
    let mut member_ways = Vec::new();
    let mut homes = 0;
    for s in records {
        let mut osm = unpack(&s.bytes)?;
        for r in osm.buildings.drain(..) {
            if seen.insert(r.id) {
                homes += usize::from(s.home);
                if let Some(m) = member_ways_of(&osm.member_ways, r.id) {
                    member_ways.push(m.clone());
                }
                kept.push(r);
            }
        }
    }
    kept.sort_by_key(|r| r.id);
    member_ways.sort_by_key(|m| m.relation);
    let refs: Vec<&BuildingRecord> = kept.iter().collect();
    let member_refs: Vec<&MemberWays> = member_ways.iter().collect();
    let body = pack_parts(&refs, &[], &[], &member_refs);
    let osm = OsmBuildings {
        buildings: kept,
        member_ways,
        ..OsmBuildings::default()
    };
    Ok((body, homes, super::replication::elements_of(&osm)))
}

/// Imports the files into `store`.
pub async fn import_files(
    files: &[PathBuf],
    store: &OsmTileStore,
    options: &ImportOptions,
) -> anyhow::Result<ImportReport> {
    anyhow::ensure!(!files.is_empty(), "name at least one OSM file to import");
    anyhow::ensure!(
        options.memory_bytes >= MIN_MEMORY_MB << 20,
        "a memory budget of at least {MIN_MEMORY_MB} MB, please"
    );
    let started = Instant::now();
    let base = options.temp_dir.clone().unwrap_or_else(std::env::temp_dir);
    let temp = tempfile::Builder::new()
        .prefix("citymesh-import-")
        .tempdir_in(&base)
        .with_context(|| format!("cannot make a temporary directory in {}", base.display()))?;
    let (files_owned, opts) = (files.to_vec(), options.clone());
    let temp_path = temp.path().to_owned();
    let spiller =
        tokio::task::spawn_blocking(move || read_files(&files_owned, &temp_path, &opts)).await??;
    let Spiller {
        spill, mut report, ..
    } = spiller;

    // Grouped into data tiles on a blocking thread, written here, in one transaction.
    let (tx, mut rx) = tokio::sync::mpsc::channel::<
        anyhow::Result<(TileCoord, Vec<u8>, usize, Elements)>,
    >(TILES_IN_FLIGHT);
    let allowance = options.memory_bytes / 4;
    let grouping = tokio::task::spawn_blocking(move || {
        let result = spill.drain(allowance, |t, records| {
            let (body, homes, elements) = data_tile_of(records)?;
            tx.blocking_send(Ok((t, body, homes, elements)))
                .map_err(|_| anyhow::anyhow!("the import stopped writing"))
        });
        if let Err(e) = result {
            let _ = tx.blocking_send(Err(e));
        }
    });
    let writing = bar(0, "storing data tiles", options.quiet);
    let mut writer = store.import_writer().await?;
    let mut batch: Vec<(TileCoord, Vec<u8>)> = Vec::new();
    let mut batch_bytes = 0u64;
    let batch_limit = (options.memory_bytes / 16).max(1 << 20);
    loop {
        let next = rx.recv().await;
        let last = next.is_none();
        if let Some(next) = next {
            let (t, body, homes, elements) = next?;
            writer.index_elements(&t, elements).await?;
            report.buildings += homes;
            report.data_tiles += 1;
            report.stored_bytes += body.len() as u64;
            batch_bytes += body.len() as u64;
            batch.push((t, body));
        }
        if batch.len() >= WRITE_BATCH || batch_bytes >= batch_limit || (last && !batch.is_empty()) {
            let changed = writer.put_many(&batch).await?;
            for ((t, _), changed) in batch.iter().zip(changed) {
                if changed {
                    report.changed_data_tiles += 1;
                    report.changed_areas.push(affected_area(t));
                }
            }
            writing.inc(batch.len() as u64);
            batch.clear();
            batch_bytes = 0;
        }
        if last {
            break;
        }
    }
    grouping.await?;
    writer.commit().await?;
    writing.finish_and_clear();
    drop(temp);
    report.seconds = started.elapsed().as_secs_f64();
    Ok(report)
}

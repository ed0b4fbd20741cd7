//! `citymesh export`: a static tree of tiles any file server or object store serves as it is
//! (how CDNs host 3D Tiles): the world tileset the server serves (`tileset.json` and the
//! `world/` files it names: nested tileset files and content at every level, the same bytes),
//! or XYZ GLB tiles (`{z}/{x}/{y}.glb`), into a directory or an S3-compatible object store
//! ([`target`]).
//!
//! The work is cut into units ([`plan`]), kept in the database ([`claims`]) and claimed under a
//! lease, so an export of any size holds a bounded amount in memory (a few units at a time),
//! resumes where it stopped (units done are not redone; a file that exists is whole and is
//! kept), and several exporters on one PostgreSQL share it. Generation is deterministic, so the
//! tree is the same byte for byte however often it was interrupted or however many exporters
//! wrote it. Within a unit the tileset file is written last; the root `tileset.json` is the
//! last file of the export.

mod claims;
pub mod plan;
pub mod target;
mod units;

use crate::cli::{EncodingArg, ExportArgs, ExportFormat, TilingArg};
use crate::server::OpenedGenerator;
use citymesh_core::geo::GeoBbox;
use citymesh_core::mesh::Encoding;
use claims::{Claimed, Claims};
use indicatif::{ProgressBar, ProgressStyle};
use plan::{Scope, Unit};
use sha2::Digest as _;
use std::collections::HashMap;
use std::io::Write as _;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use target::ExportTarget;
use tokio_util::sync::CancellationToken;

/// Units one exporter works on at once (each with up to `--workers` tiles generating): the next
/// unit's summaries are made while the last one's tiles finish.
const UNITS_AT_ONCE: usize = 2;

/// How long an exporter waits before asking again when every unit left is another's or waits
/// for units below it.
const IDLE_WAIT: Duration = Duration::from_millis(250);

/// What an export did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct ExportSummary {
    /// Files in the finished tree.
    pub files: u64,
    /// Of those, written by this run.
    pub written: u64,
    /// Files this run found written already (by an earlier run, or another exporter) and kept.
    pub kept: u64,
    /// Scenes (tiles) this run generated: one per file it wrote that is content.
    pub generated: u64,
    /// Units of work this run did.
    pub units: u64,
    /// Of those, units an earlier claim held (an exporter killed holding them, or stopped by an
    /// error): taken over.
    pub taken_over: u64,
    /// Bytes of the finished tree.
    pub bytes: u64,
    /// Wall time of the run, in milliseconds.
    pub ms: u64,
}

/// What the format writes.
#[derive(Debug, Clone, Copy)]
enum Format {
    Tiles3d,
    Xyz { from: u8, to: u8 },
}

/// An export under way: what every unit needs.
pub(crate) struct Exporter<'a> {
    generator: &'a crate::pipeline::Generator,
    out: &'a ExportTarget,
    encoding: Encoding,
    format: Format,
    scope: Scope,
    claims: Claims,
    /// What content versions are salted with (as the server's).
    data_version: String,
    workers: usize,
    lease: Duration,
    /// Files written and kept by this run.
    written: AtomicU64,
    kept: AtomicU64,
    /// Units this run took over from an earlier claim.
    taken_over: AtomicU64,
    /// Files finished in units of this run not yet marked done.
    running_files: AtomicU64,
    bar: ProgressBar,
    /// Progress lines without a terminal (the last percent printed).
    lines: bool,
    last_percent: AtomicU64,
}

/// Runs the export `args` describes with the generator `opened`.
pub async fn run(opened: &OpenedGenerator, args: &ExportArgs) -> anyhow::Result<ExportSummary> {
    let started = Instant::now();
    let generator = &opened.generator;
    anyhow::ensure!(
        args.tiling == TilingArg::Explicit,
        "--tiling implicit: an export writes the world tileset, explicit in nested tileset files; \
         a server serves an implicit tileset of a box at /3dtiles/tileset.json?bbox=...&tiling=implicit"
    );
    anyhow::ensure!(
        args.serve.world_area.is_none(),
        "--world-area: an export writes the data held; import or fetch the area first"
    );
    anyhow::ensure!(
        args.lease_s.is_finite() && (1.0..=86_400.0).contains(&args.lease_s),
        "--lease-s must be 1 to 86400 seconds"
    );
    let bbox: Option<GeoBbox> = args
        .bbox
        .as_deref()
        .map(|b| b.parse().map_err(|e| anyhow::anyhow!("--bbox: {e}")))
        .transpose()?;
    let encoding = Encoding::from(args.encoding.unwrap_or(match args.format {
        ExportFormat::Tiles3d => EncodingArg::Meshopt,
        ExportFormat::Xyz => EncodingArg::Plain,
    }));
    let format = match args.format {
        ExportFormat::Tiles3d => Format::Tiles3d,
        ExportFormat::Xyz => {
            let (from, to) = parse_zooms(args.zooms.as_deref())?;
            Format::Xyz { from, to }
        }
    };
    let out = ExportTarget::parse(&args.out)?;
    out.prepare().await?;

    // The plan, the same in every exporter of this export.
    let scope = match (format, bbox) {
        (Format::Xyz { .. }, Some(b)) => Scope::Box(b),
        _ => {
            let tiles = generator
                .source
                .data_tiles()
                .await
                .map_err(|e| anyhow::anyhow!("listing the data tiles: {e}"))?;
            Scope::of_data_tiles(&tiles, bbox.as_ref())
        }
    };
    let units: Vec<Unit> = match format {
        Format::Tiles3d => plan::tiles3d_units(&scope),
        Format::Xyz { from, to } => plan::xyz_units(&scope, from, to),
    };
    anyhow::ensure!(
        !units.is_empty(),
        "nothing to export: {}",
        match &bbox {
            Some(b) => format!("no data tile holds buildings in {b}"),
            None => "the data holds no buildings".to_owned(),
        }
    );
    let describe = format!(
        "{} encoding={} bbox={} zooms={} data={} out={}",
        match format {
            Format::Tiles3d => "3dtiles".to_owned(),
            Format::Xyz { from, to } => format!("xyz {from}-{to}"),
        },
        encoding,
        bbox.map_or_else(|| "all".to_owned(), |b| b.to_string()),
        args.zooms.as_deref().unwrap_or("-"),
        opened.data_version,
        out.identity(),
    );
    let export_id = export_id(&describe);
    let claims = Claims::open(
        &opened.database,
        &export_id,
        &describe,
        &units,
        crate::clock::Clock::system(),
    )
    .await?;
    let parents: HashMap<i64, Option<i64>> = units.iter().map(|u| (u.id, u.parent)).collect();
    drop(units);
    let ex = Exporter {
        generator,
        out: &out,
        encoding,
        format,
        scope,
        claims,
        data_version: opened.data_version.clone(),
        workers: args.worker_count(),
        lease: Duration::from_secs_f64(args.lease_s),
        written: AtomicU64::new(0),
        kept: AtomicU64::new(0),
        taken_over: AtomicU64::new(0),
        running_files: AtomicU64::new(0),
        bar: progress(args.quiet),
        lines: false,
        last_percent: AtomicU64::new(0),
    };
    let ex = Exporter {
        lines: ex.bar.is_hidden() && !args.quiet,
        ..ex
    };
    ex.verify_done(&parents).await?;
    let generated_before = generator.metrics.generations.get();
    let p = ex.claims.progress().await?;
    ex.bar.set_length(p.files_total);
    ex.bar.set_position(p.files_done);
    ex.bar.reset_eta();

    let stop = CancellationToken::new();
    let loops = (0..UNITS_AT_ONCE).map(|_| ex.work(&stop));
    let done: Vec<u64> = futures_util::future::try_join_all(loops).await?;
    ex.bar.finish_and_clear();

    let p = ex.claims.progress().await?;
    let summary = ExportSummary {
        files: p.files_done,
        written: ex.written.load(Ordering::Relaxed),
        kept: ex.kept.load(Ordering::Relaxed),
        generated: generator.metrics.generations.get() - generated_before,
        units: done.iter().sum(),
        taken_over: ex.taken_over.load(Ordering::Relaxed),
        bytes: out.bytes().await?,
        ms: started.elapsed().as_millis() as u64,
    };
    if let Some(path) = &args.report {
        std::fs::write(path, serde_json::to_vec_pretty(&summary)?)
            .map_err(|e| anyhow::anyhow!("--report {}: {e}", path.display()))?;
    }
    if !args.quiet {
        println!(
            "exported {} files to {} ({} written now, {} kept, {} scenes generated, {} units): \
             {:.1} MB in {:.1} s",
            summary.files,
            out,
            summary.written,
            summary.kept,
            summary.generated,
            summary.units,
            summary.bytes as f64 / 1e6,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(summary)
}

/// The export's id in the database: a digest of what it writes, from which data, to where.
fn export_id(describe: &str) -> String {
    let digest = sha2::Sha256::digest(describe.as_bytes());
    digest[..12].iter().map(|b| format!("{b:02x}")).collect()
}

impl Exporter<'_> {
    /// Units done whose last file is missing (the tree was removed or cut since) are done
    /// again, with every unit above them.
    async fn verify_done(&self, parents: &HashMap<i64, Option<i64>>) -> anyhow::Result<()> {
        let mut again = std::collections::BTreeSet::new();
        for unit in self.claims.done_units().await? {
            if unit.files == 0 {
                continue;
            }
            let marker = units::marker(self.format, &self.scope, &unit.tile);
            if !self.out.exists(&marker).await? {
                let mut id = Some(unit.id);
                while let Some(i) = id {
                    again.insert(i);
                    id = parents.get(&i).copied().flatten();
                }
            }
        }
        if !again.is_empty() {
            tracing::warn!(
                units = again.len(),
                "units done whose files are gone: doing them again"
            );
        }
        for id in again {
            self.claims.reset(id).await?;
        }
        Ok(())
    }

    /// Claims and does units until every unit is done (by anyone); answers how many it did.
    /// On an error it gives its unit back, stops the other loops, and answers the error.
    async fn work(&self, stop: &CancellationToken) -> anyhow::Result<u64> {
        let mut done = 0u64;
        loop {
            if stop.is_cancelled() {
                return Ok(done);
            }
            let Some(unit) = self.claims.claim(self.lease).await? else {
                let p = self.claims.progress().await?;
                if p.units_done == p.units {
                    return Ok(done);
                }
                tokio::select! {
                    () = tokio::time::sleep(IDLE_WAIT) => {}
                    () = stop.cancelled() => return Ok(done),
                }
                continue;
            };
            let outcome = tokio::select! {
                r = self.held(&unit) => r,
                () = stop.cancelled() => Err(anyhow::anyhow!("stopped")),
            };
            match outcome {
                Ok(Some((files, summary))) => {
                    self.claims.done(&unit, files, summary).await?;
                    self.running_files
                        .fetch_sub(u64::try_from(files).unwrap_or(0), Ordering::Relaxed);
                    done += 1;
                    if unit.again {
                        self.taken_over.fetch_add(1, Ordering::Relaxed);
                    }
                    self.refresh().await?;
                }
                // Another exporter took the unit over: it writes the same files.
                Ok(None) => {}
                Err(e) => {
                    stop.cancel();
                    if let Err(r) = self.claims.release(&unit).await {
                        tracing::warn!("cannot give unit {} back: {r}", unit.id);
                    }
                    return Err(e);
                }
            }
        }
    }

    /// Does `unit` while extending its lease; `None` when the lease was lost to another
    /// exporter (the unit's work is dropped).
    async fn held(&self, unit: &Claimed) -> anyhow::Result<Option<(i64, Option<Vec<u8>>)>> {
        let keep = async {
            loop {
                tokio::time::sleep(self.lease / 3).await;
                match self.claims.extend(unit, self.lease).await {
                    Ok(true) => {}
                    Ok(false) => return Ok::<_, anyhow::Error>(()),
                    Err(e) => tracing::warn!("cannot extend the lease of unit {}: {e}", unit.id),
                }
            }
        };
        tokio::select! {
            r = units::run(self, unit) => r.map(Some),
            lost = keep => {
                lost?;
                tracing::warn!(unit = unit.id, "another exporter took this unit over");
                Ok(None)
            }
        }
    }

    /// The bar from the database: units done by every exporter, and this one's files since.
    async fn refresh(&self) -> anyhow::Result<()> {
        let p = self.claims.progress().await?;
        self.bar.set_length(p.files_total);
        self.bar
            .set_position(p.files_done + self.running_files.load(Ordering::Relaxed));
        self.line(p.files_done, p.files_total);
        Ok(())
    }

    /// A file is finished (written or kept).
    fn file_done(&self, written: bool) {
        if written {
            self.written.fetch_add(1, Ordering::Relaxed);
        } else {
            self.kept.fetch_add(1, Ordering::Relaxed);
        }
        self.running_files.fetch_add(1, Ordering::Relaxed);
        self.bar.inc(1);
    }

    /// Without a terminal (logs, CI, a parent process) progress is a line per percent.
    fn line(&self, done: u64, total: u64) {
        if !self.lines || total == 0 {
            return;
        }
        let percent = done * 100 / total;
        if self.last_percent.fetch_max(percent, Ordering::Relaxed) < percent {
            let rate = self.bar.per_sec();
            // A reader gone (a closed pipe) stops the lines, not the export.
            let _ = writeln!(
                std::io::stdout().lock(),
                "{done}/{total} files ({percent} %, {rate:.1} files/s)"
            );
        }
    }
}

/// `A-B` (or `A`): the zoom levels of an XYZ export; default 16.
fn parse_zooms(text: Option<&str>) -> anyhow::Result<(u8, u8)> {
    let text = text.unwrap_or("16");
    let (a, b) = text.split_once('-').unwrap_or((text, text));
    let zoom = |t: &str| -> anyhow::Result<u8> {
        let z: u8 = t
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("--zooms: '{t}' is not a zoom level"))?;
        anyhow::ensure!(z <= 22, "--zooms: {z} is above 22");
        Ok(z)
    };
    let (a, b) = (zoom(a)?, zoom(b)?);
    anyhow::ensure!(a <= b, "--zooms: {a} is above {b}");
    Ok((a, b))
}

fn progress(quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(0);
    let style = ProgressStyle::with_template(
        "{spinner} exporting [{bar:30}] {pos}/{len} files, {per_sec}, {elapsed}, about {eta} left",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zoom_ranges_parse_and_wrong_ones_say_why() {
        assert_eq!(parse_zooms(None).unwrap(), (16, 16));
        assert_eq!(parse_zooms(Some("14-17")).unwrap(), (14, 17));
        assert_eq!(parse_zooms(Some("15")).unwrap(), (15, 15));
        let e = parse_zooms(Some("17-14")).unwrap_err().to_string();
        assert!(e.contains("17 is above 14"), "{e}");
        assert!(parse_zooms(Some("x")).is_err());
        assert!(parse_zooms(Some("30")).is_err());
    }
}

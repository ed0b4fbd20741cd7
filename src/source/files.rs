//! The `--osm` files (or the procedural demo city), read once at start-up and held in memory.

use super::data_tiles::data_tile::DATA_ZOOM;
use super::{AreaBuildings, BuildingSource, DataChanged, PriorScope, SourceError, skips_near};
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{BuildingRecord, OsmError, OsmFormat, Repaired, Skipped, read_buildings};
use citymesh_core::roof_prior::PREDICTION_BYTES;
use futures_util::future::BoxFuture;
use std::collections::{HashMap, HashSet};
use std::hash::{DefaultHasher, Hash, Hasher};
use std::io::{BufRead as _, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tokio::sync::broadcast;

/// Why an OSM file could not be used. Start-up stops with this message.
#[derive(Debug, thiserror::Error)]
pub enum OsmFileError {
    #[error("cannot read the OSM file {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {source} (give OSM PBF, OSM XML or Overpass JSON, optionally .gz)")]
    Format { path: String, source: OsmError },
    #[error(
        "{path}: more than {cap} bytes{} (the limit is 4 GiB, and a gzip file may grow at most \
         100 times its size): split the file, e.g. with osmium extract",
        if *gzip { " once gunzipped" } else { "" }
    )]
    TooLarge { path: String, cap: u64, gzip: bool },
}

/// Most buildings whose files teach one roof prior together (about a city of half a million
/// people): a fit learns from at most 5,000 of them but predicts, and keeps, every untagged one.
pub const MAX_WHOLE_PRIOR: usize = 200_000;

/// Buildings held in memory: the `--osm` files, or the demo city.
#[derive(Debug)]
pub struct FileSource {
    pub set: Arc<BuildingSet>,
    /// Buildings that could not be assembled from the files (missing nodes, unclosed rings...),
    /// with where the files place them; `/scene/stats` reports those of its area.
    pub load_skips: Vec<Skipped>,
    /// Buildings built with less than the files describe.
    pub repaired: Arc<Vec<Repaired>>,
    /// Changes whenever the files change, so cached tiles built from old data are not reused.
    pub fingerprint: String,
    /// The zoom of the tiles the files' roof priors learn in; `None`: one prior learns from
    /// every building ([`FileSource::bound_priors`]).
    prior_zoom: Option<u8>,
    /// Files never change while the server runs: nothing is ever sent.
    changes: broadcast::Sender<DataChanged>,
}

impl FileSource {
    /// Buildings given up front (the demo city), under a fixed fingerprint.
    pub fn new(set: BuildingSet, fingerprint: &str) -> Self {
        let prior_zoom = whole_or_data_tiles(set.records().len());
        Self {
            set: Arc::new(set),
            load_skips: Vec::new(),
            repaired: Arc::default(),
            fingerprint: fingerprint.to_owned(),
            prior_zoom,
            changes: broadcast::channel(1).0,
        }
    }

    /// Cuts the files' buildings into prior scopes small enough that each prior weighs at most
    /// `max_bytes` (so the priors' memory share keeps it, and a cached tile never waits for a
    /// fit again): all of them when they fit, else the tiles of the coarsest zoom, from the
    /// data tiles' on, whose every tile fits (at most [`MAX_PRIOR_ZOOM`]). Blocking (a pass
    /// over the buildings per zoom tried).
    pub fn bound_priors(mut self, max_bytes: u64) -> Self {
        self.prior_zoom = prior_zoom(self.set.records(), max_bytes);
        self
    }
}

impl BuildingSource for FileSource {
    fn buildings<'a>(
        &'a self,
        bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<AreaBuildings, SourceError>> {
        Box::pin(async move {
            Ok(AreaBuildings {
                set: self.set.clone(),
                origin: "files".to_owned(),
                load_skips: skips_near(&self.load_skips, bbox),
                repaired: self.repaired.clone(),
            })
        })
    }

    fn subscribe(&self) -> broadcast::Receiver<DataChanged> {
        self.changes.subscribe()
    }

    fn fingerprint(&self) -> &str {
        &self.fingerprint
    }

    fn summary(&self) -> usize {
        self.set.records().len()
    }

    fn extent(&self) -> Option<GeoBbox> {
        self.set.extent()
    }

    fn held_buildings<'a>(
        &'a self,
        _bbox: &'a GeoBbox,
    ) -> BoxFuture<'a, Result<Arc<BuildingSet>, SourceError>> {
        Box::pin(async move { Ok(self.set.clone()) })
    }

    fn data_tiles<'a>(&'a self) -> BoxFuture<'a, Result<Vec<TileCoord>, SourceError>> {
        let zoom = super::data_tiles::data_tile::DATA_ZOOM;
        let tiles: std::collections::BTreeSet<TileCoord> = self
            .set
            .clusters()
            .iter()
            .map(|c| c.xyz_tile(zoom))
            .collect();
        Box::pin(async move { Ok(tiles.into_iter().collect()) })
    }

    /// All the files' buildings teach one prior, up to [`MAX_WHOLE_PRIOR`] buildings and the
    /// priors' memory share; larger file sets are cut into tiles ([`FileSource::bound_priors`]),
    /// so a fit stays bounded and its prior is kept.
    fn prior_scope(&self, lon: f64, lat: f64) -> PriorScope {
        match self.prior_zoom {
            None => PriorScope::Everything,
            Some(z) => PriorScope::DataTile(TileCoord::containing(z, lon, lat)),
        }
    }

    fn prior_records<'a>(
        &'a self,
        scope: PriorScope,
    ) -> BoxFuture<'a, Result<Vec<Arc<BuildingRecord>>, SourceError>> {
        Box::pin(async move {
            Ok(match scope {
                PriorScope::Everything => self.set.records().to_vec(),
                PriorScope::DataTile(t) => {
                    let all = self.set.records();
                    self.set
                        .clusters_intersecting(&t.bounds())
                        .into_iter()
                        .flat_map(|c| c.records.iter().map(|&i| all[i].clone()))
                        .collect()
                }
            })
        })
    }
}

/// Largest OSM file accepted, read or gunzipped (4 GiB).
pub const MAX_OSM_BYTES: u64 = 4 << 30;
/// Most a gzip file may grow when gunzipped, as a multiple of its size: OSM XML and Overpass
/// JSON compress 10 to 20 times, so more is a gzip bomb (a file of gzipped zeros grows about a
/// thousand times).
pub const MAX_GZIP_RATIO: u64 = 100;
/// Bytes read before the format is recognised: a file that is no OSM format is refused after
/// these, however large it is (a sparse file of zeros, a video renamed `.osm`).
const SNIFF_BYTES: u64 = 64;

/// The bytes of an OSM file, gunzipped when it is gzip. The format is recognised from the first
/// bytes before the rest is read, and what is read is capped ([`MAX_OSM_BYTES`], and
/// [`MAX_GZIP_RATIO`] times the file for gzip): a bad or hostile file is refused, naming it,
/// after at most the cap.
pub fn read_osm_file(path: &Path) -> Result<Vec<u8>, OsmFileError> {
    let name = || path.display().to_string();
    let io = |source| OsmFileError::Io {
        path: name(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    let mut file = std::io::BufReader::new(file);
    let gzip = file.fill_buf().map_err(io)?.starts_with(&[0x1f, 0x8b]);
    let (mut reader, cap): (Box<dyn Read>, u64) = if gzip {
        let cap = size
            .saturating_mul(MAX_GZIP_RATIO)
            .clamp(1 << 20, MAX_OSM_BYTES);
        (Box::new(flate2::bufread::GzDecoder::new(file)), cap)
    } else {
        (Box::new(file), MAX_OSM_BYTES)
    };
    let mut out = Vec::new();
    (&mut reader)
        .take(SNIFF_BYTES)
        .read_to_end(&mut out)
        .map_err(io)?;
    if OsmFormat::sniff(&out).is_none() {
        return Err(OsmFileError::Format {
            path: name(),
            source: OsmError::UnknownFormat,
        });
    }
    if !gzip && size > MAX_OSM_BYTES {
        return Err(OsmFileError::TooLarge {
            path: name(),
            cap: MAX_OSM_BYTES,
            gzip,
        });
    }
    reader
        .take(cap.saturating_add(1).saturating_sub(out.len() as u64))
        .read_to_end(&mut out)
        .map_err(io)?;
    if out.len() as u64 > cap {
        return Err(OsmFileError::TooLarge {
            path: name(),
            cap,
            gzip,
        });
    }
    Ok(out)
}

/// Reads every file; a building found in several files is kept once. Blocking.
pub fn load_osm_files(paths: &[PathBuf]) -> Result<FileSource, OsmFileError> {
    let mut records: Vec<BuildingRecord> = Vec::new();
    let mut seen = HashSet::new();
    let mut load_skips = Vec::new();
    let mut repaired = Vec::new();
    let mut h = DefaultHasher::new();
    for path in paths {
        let bytes = read_osm_file(path)?;
        bytes.len().hash(&mut h);
        path.hash(&mut h);
        if let Ok(modified) = std::fs::metadata(path).and_then(|m| m.modified()) {
            modified.hash(&mut h);
        }
        let osm = read_buildings(&bytes).map_err(|source| OsmFileError::Format {
            path: path.display().to_string(),
            source,
        })?;
        tracing::info!(
            file = %path.display(),
            buildings = osm.buildings.len(),
            skipped = osm.skipped.len(),
            "OSM file read"
        );
        for skip in &osm.skipped {
            tracing::warn!(file = %path.display(), id = %skip.id, reason = skip.reason.name(), "building skipped");
        }
        load_skips.extend(osm.skipped);
        repaired.extend(osm.repaired);
        for b in osm.buildings {
            if seen.insert(b.id) {
                records.push(b);
            }
        }
    }
    let set = BuildingSet::new(records);
    Ok(FileSource {
        prior_zoom: whole_or_data_tiles(set.records().len()),
        set: Arc::new(set),
        load_skips,
        repaired: Arc::new(repaired),
        fingerprint: format!("{:016x}", h.finish()),
        changes: broadcast::channel(1).0,
    })
}

/// The deepest zoom the files' prior scopes are cut to (tiles about 100 m wide).
pub const MAX_PRIOR_ZOOM: u8 = 18;

/// One prior over every building (`None`) up to [`MAX_WHOLE_PRIOR`] of them, else data tiles.
fn whole_or_data_tiles(buildings: usize) -> Option<u8> {
    (buildings > MAX_WHOLE_PRIOR).then_some(DATA_ZOOM)
}

/// The zoom of the tiles whose buildings' priors each weigh at most `max_bytes` (see
/// [`FileSource::bound_priors`]); a building counts in the tile of its outline's first node,
/// as [`BuildingSource::prior_scope`] places it.
fn prior_zoom(records: &[Arc<BuildingRecord>], max_bytes: u64) -> Option<u8> {
    let fits = |n: usize| {
        n <= MAX_WHOLE_PRIOR && (n as u64).saturating_mul(PREDICTION_BYTES as u64) <= max_bytes
    };
    if fits(records.len()) {
        return None;
    }
    let firsts: Vec<(f64, f64)> = records
        .iter()
        .filter_map(|r| r.outers.first()?.nodes.first().map(|n| (n.lon, n.lat)))
        .collect();
    (DATA_ZOOM..MAX_PRIOR_ZOOM)
        .find(|&z| {
            let mut per_tile: HashMap<TileCoord, usize> = HashMap::new();
            for &(lon, lat) in &firsts {
                *per_tile
                    .entry(TileCoord::containing(z, lon, lat))
                    .or_default() += 1;
            }
            per_tile.values().all(|&n| fits(n))
        })
        .or(Some(MAX_PRIOR_ZOOM))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // test code: failing is the point
    use super::*;
    use citymesh_core::procedural::{ProceduralParams, generate_city};

    fn gzip(bytes: &[u8]) -> Vec<u8> {
        use std::io::Write as _;
        let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(bytes).unwrap();
        z.finish().unwrap()
    }

    #[test]
    fn hostile_files_are_refused_naming_them_after_a_bounded_read() {
        let dir = tempfile::tempdir().unwrap();
        // A sparse file of 2 GiB (zeros): refused on its first bytes.
        let sparse = dir.path().join("sparse.osm");
        std::fs::File::create(&sparse)
            .unwrap()
            .set_len(2 << 30)
            .unwrap();
        let e = read_osm_file(&sparse).unwrap_err();
        assert!(
            matches!(
                e,
                OsmFileError::Format {
                    source: OsmError::UnknownFormat,
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("sparse.osm"), "{e}");
        // Gzipped zeros: refused on their first gunzipped bytes.
        let zeros = dir.path().join("zeros.osm.gz");
        std::fs::write(&zeros, gzip(&vec![0u8; 64 << 20])).unwrap();
        assert!(matches!(
            read_osm_file(&zeros).unwrap_err(),
            OsmFileError::Format {
                source: OsmError::UnknownFormat,
                ..
            }
        ));
        // XML that grows 1,000-fold: refused at the cap, 100 times the file (at least 1 MiB).
        let mut xml = b"<osm>".to_vec();
        xml.resize(64 << 20, b' ');
        let bomb = dir.path().join("bomb.osm.gz");
        let packed = gzip(&xml);
        assert!(packed.len() < (64 << 20) / 500);
        std::fs::write(&bomb, &packed).unwrap();
        let e = read_osm_file(&bomb).unwrap_err();
        let cap = (packed.len() as u64 * MAX_GZIP_RATIO).max(1 << 20);
        assert!(
            matches!(e, OsmFileError::TooLarge { cap: c, gzip: true, .. } if c == cap),
            "{e}"
        );
        assert!(e.to_string().contains("bomb.osm.gz"), "{e}");
        // A gzip file within the ratio reads whole.
        let fine = dir.path().join("fine.osm.gz");
        let small = b"<osm version=\"0.6\"></osm>".to_vec();
        std::fs::write(&fine, gzip(&small)).unwrap();
        assert_eq!(read_osm_file(&fine).unwrap(), small);
    }

    #[test]
    fn large_file_sets_teach_priors_by_data_tile() {
        assert_eq!(whole_or_data_tiles(1_000), None);
        assert_eq!(whole_or_data_tiles(MAX_WHOLE_PRIOR + 1), Some(14));
    }

    /// Round 3, item 6: a prior heavier than the priors' memory share was never kept, so every
    /// tile with `roofs=inferred`, cached or not, fitted it again. Scopes are cut until each
    /// prior fits.
    #[test]
    fn prior_scopes_are_cut_until_each_prior_fits_its_bytes() {
        let city = generate_city(&ProceduralParams::default()).unwrap();
        let n = city.records.len();
        let records: Vec<Arc<BuildingRecord>> = city.records.into_iter().map(Arc::new).collect();
        let whole = (n * PREDICTION_BYTES) as u64;
        assert_eq!(prior_zoom(&records, whole), None);
        let max_bytes = whole / 10;
        let z = prior_zoom(&records, max_bytes).unwrap();
        assert!((DATA_ZOOM..=MAX_PRIOR_ZOOM).contains(&z));
        let mut per_tile: HashMap<TileCoord, usize> = HashMap::new();
        for r in &records {
            let n = &r.outers[0].nodes[0];
            *per_tile
                .entry(TileCoord::containing(z, n.lon, n.lat))
                .or_default() += 1;
        }
        assert!(per_tile.len() > 1);
        let heaviest = per_tile.values().max().unwrap() * PREDICTION_BYTES;
        assert!(heaviest as u64 <= max_bytes, "{heaviest} bytes at zoom {z}");
    }

    #[tokio::test]
    async fn a_data_tile_scope_holds_the_buildings_reaching_into_it() {
        let city = generate_city(&ProceduralParams::default()).unwrap();
        let n = city.records.len();
        let source = FileSource::new(BuildingSet::new(city.records), "demo");
        let all = source.prior_records(PriorScope::Everything).await.unwrap();
        assert_eq!(all.len(), n);
        let (lon, lat) = city.bbox.center();
        let tile = TileCoord::containing(DATA_ZOOM, lon, lat);
        let some = source
            .prior_records(PriorScope::DataTile(tile))
            .await
            .unwrap();
        assert!(!some.is_empty() && some.len() <= n);
        let far = TileCoord::containing(DATA_ZOOM, lon + 1.0, lat);
        let none = source
            .prior_records(PriorScope::DataTile(far))
            .await
            .unwrap();
        assert!(none.is_empty());
    }
}

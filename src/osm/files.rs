//! Reading OSM files from disk into the building set the server serves.

use citymesh_core::building::set::BuildingSet;
use citymesh_core::osm::{BuildingRecord, OsmError, read_buildings};
use std::collections::HashSet;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
}

/// The buildings of all `--osm` files.
#[derive(Debug, Default)]
pub struct OsmData {
    pub set: Arc<BuildingSet>,
    /// Buildings that could not be assembled from the files (missing nodes, unclosed rings...).
    pub skipped_at_load: usize,
    /// Changes whenever the files change, so cached tiles built from old data are not reused.
    pub fingerprint: String,
}

/// Largest decompressed OSM file accepted (4 GiB): guards against gzip bombs.
const MAX_OSM_BYTES: u64 = 4 << 30;

/// The bytes of an OSM file, gunzipped when it is gzip.
pub fn read_osm_file(path: &Path) -> Result<Vec<u8>, OsmFileError> {
    let io = |source| OsmFileError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut raw = Vec::new();
    std::fs::File::open(path)
        .map_err(io)?
        .read_to_end(&mut raw)
        .map_err(io)?;
    if raw.starts_with(&[0x1f, 0x8b]) {
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(&raw[..])
            .take(MAX_OSM_BYTES)
            .read_to_end(&mut out)
            .map_err(io)?;
        return Ok(out);
    }
    Ok(raw)
}

/// Reads every file; a building found in several files is kept once. Blocking.
pub fn load_osm_files(paths: &[PathBuf]) -> Result<OsmData, OsmFileError> {
    let mut records: Vec<BuildingRecord> = Vec::new();
    let mut seen = HashSet::new();
    let mut skipped = 0;
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
        skipped += osm.skipped.len();
        for b in osm.buildings {
            if seen.insert(b.id) {
                records.push(b);
            }
        }
    }
    Ok(OsmData {
        set: Arc::new(BuildingSet::new(records)),
        skipped_at_load: skipped,
        fingerprint: format!("{:016x}", h.finish()),
    })
}

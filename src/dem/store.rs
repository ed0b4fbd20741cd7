//! Lazy, bounded loading of SRTM tiles for the areas requests ask for.

use super::files::{read_hgt, read_hgt_band};
use citymesh_core::geo::GeoBbox;
use citymesh_core::terrain::{ElevationModel, HgtTile, dem_tiles_for, parse_hgt_name};
use std::collections::{BTreeMap, HashMap};
use std::hash::{DefaultHasher, Hash, Hasher};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

type TileKey = (i32, i32);

/// The DEM files of one directory.
pub struct DemStore {
    files: BTreeMap<TileKey, PathBuf>,
    cache: moka::sync::Cache<TileKey, Arc<HgtTile>>,
    /// Files that failed to load, with the reason; treated as missing from then on.
    broken: Mutex<HashMap<TileKey, String>>,
    fingerprint: String,
}

/// The elevation model for one request and what it lacks.
pub struct DemLookup {
    pub model: ElevationModel,
    /// Names of 1x1 degree areas the request touches that no usable file covers.
    pub missing: Vec<String>,
}

impl DemStore {
    /// Bytes the parsed files in memory weigh now.
    pub fn memory_use(&self) -> u64 {
        self.cache.run_pending_tasks();
        self.cache.weighted_size()
    }

    /// Indexes the SRTM files under `dir` (recursively). A missing directory gives an empty store:
    /// all ground is the flat fallback.
    pub fn open(dir: &Path, cache_bytes: u64) -> Self {
        let mut files = BTreeMap::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            let Ok(entries) = std::fs::read_dir(&d) else {
                if d == dir {
                    tracing::warn!(dir = %dir.display(), "DEM directory not readable: ground will be flat at 0 m");
                }
                continue;
            };
            for entry in entries.flatten() {
                let path = entry.path();
                if path.is_dir() {
                    stack.push(path);
                    continue;
                }
                let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
                    continue;
                };
                let lower = name.to_ascii_lowercase();
                if !(lower.ends_with(".hgt")
                    || lower.ends_with(".hgt.gz")
                    || lower.ends_with(".hgt.zip"))
                {
                    continue;
                }
                match parse_hgt_name(name) {
                    Ok(key) => {
                        if let Some(previous) = files.insert(key, path.clone()) {
                            tracing::warn!(kept = %path.display(), ignored = %previous.display(), "two DEM files for one area");
                        }
                    }
                    Err(e) => tracing::warn!(file = %path.display(), "{e}"),
                }
            }
        }
        tracing::info!(dir = %dir.display(), files = files.len(), "DEM store indexed");
        let fingerprint = fingerprint(&files);
        let cache = moka::sync::Cache::builder()
            .max_capacity(cache_bytes)
            .weigher(|_, tile: &Arc<HgtTile>| u32::try_from(tile.byte_size()).unwrap_or(u32::MAX))
            .build();
        Self {
            files,
            cache,
            broken: Mutex::new(HashMap::new()),
            fingerprint,
        }
    }

    /// Number of indexed files.
    pub fn file_count(&self) -> usize {
        self.files.len()
    }

    /// Changes whenever the set of files (names, sizes, modification times) changes, so cached
    /// results built from the old files are not reused.
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }

    /// Loads what a ground grid over `bbox` needs. Blocking: call it from `spawn_blocking`.
    pub fn lookup(&self, bbox: &GeoBbox) -> DemLookup {
        let mut tiles = Vec::new();
        let mut missing = Vec::new();
        for key in dem_tiles_for(bbox) {
            match self.tile(key) {
                Some(t) => tiles.push(t),
                None => missing.push(citymesh_core::terrain::hgt_name(key.0, key.1)),
            }
        }
        DemLookup {
            model: ElevationModel::new(tiles),
            missing,
        }
    }

    /// What a ground grid over `bbox` needs, read for one use: of each uncompressed file only
    /// the rows the box covers, and nothing kept (packed files are read whole, through the
    /// cache). For one-off commands such as `citymesh scene`; a server keeps whole files.
    pub fn read_for(&self, bbox: &GeoBbox) -> DemLookup {
        let mut tiles = Vec::new();
        let mut missing = Vec::new();
        for key in dem_tiles_for(bbox) {
            let band = self
                .files
                .get(&key)
                .and_then(|path| read_hgt_band(path, key.0, key.1, bbox.min_lat(), bbox.max_lat()));
            let tile = match band {
                Some(Ok(tile)) => Some(Arc::new(tile)),
                Some(Err(e)) => {
                    tracing::warn!(reason = %e, "DEM file unusable: treated as missing");
                    None
                }
                None => self.tile(key),
            };
            match tile {
                Some(t) => tiles.push(t),
                None => missing.push(citymesh_core::terrain::hgt_name(key.0, key.1)),
            }
        }
        DemLookup {
            model: ElevationModel::new(tiles),
            missing,
        }
    }

    fn tile(&self, key: TileKey) -> Option<Arc<HgtTile>> {
        let path = self.files.get(&key)?;
        if self.broken.lock().is_ok_and(|b| b.contains_key(&key)) {
            return None;
        }
        let loaded = self
            .cache
            .try_get_with(key, || -> Result<Arc<HgtTile>, String> {
                let tile = read_hgt(path, key.0, key.1).map_err(|e| e.to_string())?;
                tracing::debug!(file = %path.display(), size = tile.size(), "DEM file loaded");
                Ok(Arc::new(tile))
            });
        match loaded {
            Ok(tile) => Some(tile),
            Err(reason) => {
                tracing::warn!(%reason, "DEM file unusable: treated as missing");
                if let Ok(mut broken) = self.broken.lock() {
                    broken.insert(key, reason.to_string());
                }
                None
            }
        }
    }
}

fn fingerprint(files: &BTreeMap<TileKey, PathBuf>) -> String {
    let mut h = DefaultHasher::new();
    for (key, path) in files {
        key.hash(&mut h);
        path.hash(&mut h);
        if let Ok(meta) = std::fs::metadata(path) {
            meta.len().hash(&mut h);
            meta.modified().ok().hash(&mut h);
        }
    }
    format!("{:016x}", h.finish())
}

//! Shared helpers for tests on the real data in `../shared/data`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point
#![allow(dead_code)]

use citymesh_core::terrain::{ElevationModel, HgtTile, parse_hgt_name};
use std::path::PathBuf;
use std::sync::Arc;

/// The real data folder: `CITYMESH_DATA_DIR`, else `../shared/data` beside the project.
pub fn data_dir() -> PathBuf {
    let dir = std::env::var_os("CITYMESH_DATA_DIR").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    );
    assert!(
        dir.join("dem").is_dir(),
        "real test data not found at {} (set CITYMESH_DATA_DIR to the folder holding dem/ and osm/)",
        dir.display()
    );
    dir
}

/// Reads and parses one HGT file of `dem/`.
pub fn hgt(name: &str) -> Arc<HgtTile> {
    let path = data_dir().join("dem").join(name);
    let bytes =
        std::fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let (lat, lon) = parse_hgt_name(name).unwrap();
    Arc::new(HgtTile::from_bytes(lat, lon, &bytes).unwrap())
}

/// The bytes of a file in `osm/`, unzipped when it ends in `.gz`.
pub fn osm_bytes(name: &str) -> Vec<u8> {
    use std::io::Read;
    let path = data_dir().join("osm").join(name);
    let raw =
        std::fs::read(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    if !name.ends_with(".gz") {
        return raw;
    }
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(&raw[..])
        .read_to_end(&mut out)
        .unwrap();
    out
}

/// A model over the named HGT files.
pub fn model(names: &[&str]) -> ElevationModel {
    ElevationModel::new(names.iter().map(|n| hgt(n)).collect())
}

/// A small deterministic random generator (xorshift64*), so tests repeat exactly.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

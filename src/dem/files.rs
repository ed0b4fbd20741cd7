//! Reading an SRTM file from disk, whatever its packaging.

use citymesh_core::terrain::{HgtError, HgtTile};
use std::path::Path;

/// Why an SRTM file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DemFileError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path} is not a readable zip archive: {detail}")]
    Zip { path: String, detail: String },
    #[error("{path} holds no .hgt file")]
    NoHgtInZip { path: String },
    /// Not HGT data (wrong size, a broken stream); decompression stops just past the largest
    /// SRTM file's size, so a zip bomb costs no more than one.
    #[error("{path}: {detail}")]
    Hgt { path: String, detail: String },
}

/// An SRTM file (`.hgt`, `.hgt.gz` or `.hgt.zip`) read and decoded as a stream, for the area
/// `(south, west)` its name gives.
pub fn read_hgt(path: &Path, south: i32, west: i32) -> Result<HgtTile, DemFileError> {
    let shown = path.display().to_string();
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default()
        .to_ascii_lowercase();
    let file = std::fs::File::open(path).map_err(|source| DemFileError::Io {
        path: shown.clone(),
        source,
    })?;
    let hgt = |e: HgtError| DemFileError::Hgt {
        path: shown.clone(),
        detail: e.to_string(),
    };
    if name.ends_with(".gz") {
        HgtTile::read(south, west, flate2::read::GzDecoder::new(file), 0).map_err(hgt)
    } else if name.ends_with(".zip") {
        let zip_err = |e: zip::result::ZipError| DemFileError::Zip {
            path: shown.clone(),
            detail: e.to_string(),
        };
        let mut archive = zip::ZipArchive::new(file).map_err(zip_err)?;
        let index = (0..archive.len())
            .find(|&i| {
                archive
                    .name_for_index(i)
                    .is_some_and(|n| n.to_ascii_lowercase().ends_with(".hgt"))
            })
            .ok_or_else(|| DemFileError::NoHgtInZip {
                path: shown.clone(),
            })?;
        let entry = archive.by_index(index).map_err(zip_err)?;
        let size = usize::try_from(entry.size()).unwrap_or(0);
        HgtTile::read(south, west, entry, size).map_err(hgt)
    } else {
        let size = file
            .metadata()
            .map_or(0, |m| usize::try_from(m.len()).unwrap_or(0));
        HgtTile::read(south, west, file, size).map_err(hgt)
    }
}

/// The rows of an uncompressed `.hgt` file that samples between `min_lat` and `max_lat` need
/// (see [`HgtTile::read_band`]); `None` for a packed (`.gz`, `.zip`) file, which has to be read
/// whole.
pub fn read_hgt_band(
    path: &Path,
    south: i32,
    west: i32,
    min_lat: f64,
    max_lat: f64,
) -> Option<Result<HgtTile, DemFileError>> {
    let name = path.file_name()?.to_str()?.to_ascii_lowercase();
    if !name.ends_with(".hgt") {
        return None;
    }
    let shown = path.display().to_string();
    let read = || {
        let file = std::fs::File::open(path).map_err(|source| DemFileError::Io {
            path: shown.clone(),
            source,
        })?;
        let bytes = file
            .metadata()
            .map_or(0, |m| usize::try_from(m.len()).unwrap_or(0));
        HgtTile::read_band(south, west, file, bytes, min_lat, max_lat).map_err(|e| {
            DemFileError::Hgt {
                path: shown.clone(),
                detail: e.to_string(),
            }
        })
    };
    Some(read())
}

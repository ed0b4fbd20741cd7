//! Reading an SRTM file's bytes from disk, whatever its packaging.

use std::io::Read;
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
}

/// Largest decompressed HGT we accept (an SRTM1 file is 25.9 MB): guards against zip bombs.
const MAX_HGT_BYTES: u64 = 26_000_000;

/// The raw HGT bytes of a `.hgt`, `.hgt.gz` or `.hgt.zip` file.
pub fn read_hgt_bytes(path: &Path) -> Result<Vec<u8>, DemFileError> {
    let shown = path.display().to_string();
    let io = |source| DemFileError::Io {
        path: shown.clone(),
        source,
    };
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default()
        .to_ascii_lowercase();
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    if name.ends_with(".gz") {
        flate2::read::GzDecoder::new(file)
            .take(MAX_HGT_BYTES)
            .read_to_end(&mut bytes)
            .map_err(io)?;
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
        entry
            .take(MAX_HGT_BYTES)
            .read_to_end(&mut bytes)
            .map_err(io)?;
    } else {
        file.take(MAX_HGT_BYTES)
            .read_to_end(&mut bytes)
            .map_err(io)?;
    }
    Ok(bytes)
}

//! Finding ONNX Runtime's shared library, which citymesh loads at run time (never at build time).

use super::ClassifierError;
use std::path::{Path, PathBuf};

/// How to get the library, for error messages and the README.
pub const INSTALL_HINT: &str = "the roof classifier needs ONNX Runtime >= 1.31 (libonnxruntime.so), \
which the PyPI wheel ships: `python3 -m venv .venv && .venv/bin/pip install 'onnxruntime>=1.31'`; \
citymesh then finds it in ./.venv, or give its path with --onnxruntime-lib or ORT_DYLIB_PATH \
(.venv/lib/python3.*/site-packages/onnxruntime/capi/libonnxruntime.so.*)";

/// The library to load: `explicit` (the `--onnxruntime-lib` flag), else `ORT_DYLIB_PATH`, else the
/// first `libonnxruntime.so*` in `./.venv/lib/python3*/site-packages/onnxruntime/capi/`, else
/// `/usr/local/lib` or `/usr/lib`. A path that is given but does not exist is an error (loading a
/// missing library can hang inside ONNX Runtime's loader, so it is never attempted).
pub fn find_runtime_library(explicit: Option<&Path>) -> Result<PathBuf, ClassifierError> {
    let given = explicit
        .map(Path::to_path_buf)
        .or_else(|| std::env::var_os("ORT_DYLIB_PATH").map(PathBuf::from));
    if let Some(path) = given {
        return if path.is_file() {
            Ok(path)
        } else {
            Err(ClassifierError::Runtime(format!(
                "{} does not exist; {INSTALL_HINT}",
                path.display()
            )))
        };
    }
    default_locations()
        .into_iter()
        .find(|p| p.is_file())
        .ok_or_else(|| ClassifierError::Runtime(format!("ONNX Runtime not found; {INSTALL_HINT}")))
}

fn default_locations() -> Vec<PathBuf> {
    let mut found = Vec::new();
    if let Ok(pythons) = std::fs::read_dir(".venv/lib") {
        let mut dirs: Vec<PathBuf> = pythons.flatten().map(|e| e.path()).collect();
        dirs.sort();
        for dir in dirs {
            let capi = dir.join("site-packages/onnxruntime/capi");
            if let Ok(files) = std::fs::read_dir(&capi) {
                let mut libs: Vec<PathBuf> = files
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| {
                        p.file_name()
                            .is_some_and(|n| n.to_string_lossy().starts_with("libonnxruntime.so"))
                    })
                    .collect();
                libs.sort();
                found.extend(libs);
            }
        }
    }
    found.push(PathBuf::from("/usr/local/lib/libonnxruntime.so"));
    found.push(PathBuf::from("/usr/lib/libonnxruntime.so"));
    found
}

//! Where an export's tree goes: a directory (or `file://` URL) on this machine, or an
//! S3-compatible object store (`s3://bucket/prefix`) through the `object_store` crate.
//!
//! Both are written so a rerun resumes: a file or object that exists is whole (a directory's
//! files are written under a temporary name and renamed; an object store's PUT is atomic), is
//! kept, and is not generated again. Generation is deterministic, so a rerun after an
//! interruption writes the same bytes a single run would.

use object_store::ObjectStore;
use object_store::aws::AmazonS3Builder;
use object_store::path::Path as ObjectPath;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Temporary files end in this; a rerun removes them.
const PARTIAL: &str = ".partial";

/// The tree's destination.
pub enum ExportTarget {
    Directory(PathBuf),
    /// An object store under a key prefix; `url` as the user gave it, for messages.
    Objects {
        store: Arc<dyn ObjectStore>,
        prefix: ObjectPath,
        url: String,
    },
}

impl ExportTarget {
    /// The target `--out` names: `s3://bucket[/prefix]` (credentials, region and endpoint from
    /// the usual `AWS_*` variables, `AWS_ENDPOINT_URL` for a store other than Amazon's), a
    /// `file://` URL, or a directory.
    pub fn parse(out: &str) -> anyhow::Result<Self> {
        if let Some(rest) = out.strip_prefix("s3://") {
            let (bucket, prefix) = rest.split_once('/').unwrap_or((rest, ""));
            anyhow::ensure!(
                !bucket.is_empty(),
                "--out {out}: no bucket (write s3://BUCKET/PREFIX)"
            );
            let store = AmazonS3Builder::from_env()
                .with_bucket_name(bucket)
                .build()
                .map_err(|e| anyhow::anyhow!("--out {out}: {e}"))?;
            return Ok(ExportTarget::Objects {
                store: Arc::new(store),
                prefix: ObjectPath::from(prefix.trim_matches('/')),
                url: out.to_owned(),
            });
        }
        if let Some(path) = out.strip_prefix("file://") {
            return Ok(ExportTarget::Directory(PathBuf::from(path)));
        }
        anyhow::ensure!(
            !out.contains("://"),
            "--out {out}: only s3:// and file:// URLs, or a directory"
        );
        Ok(ExportTarget::Directory(PathBuf::from(out)))
    }

    /// Ready to write: a directory is created and cleared of an interrupted run's temporary
    /// files; an object store is asked once, so a wrong endpoint or credentials fail now.
    pub async fn prepare(&self) -> anyhow::Result<()> {
        match self {
            ExportTarget::Directory(dir) => {
                std::fs::create_dir_all(dir)?;
                remove_partial_files(dir)?;
            }
            ExportTarget::Objects { store, prefix, url } => {
                use futures_util::StreamExt;
                if let Some(Err(e)) = store.list(Some(prefix)).next().await {
                    anyhow::bail!("--out {url}: the object store answers: {e}");
                }
            }
        }
        Ok(())
    }

    /// What names the target the same in every exporter writing to it: an object store's URL,
    /// a directory's absolute path.
    pub fn identity(&self) -> String {
        match self {
            ExportTarget::Directory(dir) => std::fs::canonicalize(dir)
                .unwrap_or_else(|_| dir.clone())
                .display()
                .to_string(),
            ExportTarget::Objects { url, .. } => url.clone(),
        }
    }

    /// Whether the file at `key` (a relative path with `/`) is there, whole.
    pub async fn exists(&self, key: &str) -> anyhow::Result<bool> {
        match self {
            ExportTarget::Directory(dir) => Ok(dir.join(key).exists()),
            ExportTarget::Objects { store, prefix, url } => {
                match store.head(&object_key(prefix, key)).await {
                    Ok(_) => Ok(true),
                    Err(object_store::Error::NotFound { .. }) => Ok(false),
                    Err(e) => Err(anyhow::anyhow!("--out {url}: {key}: {e}")),
                }
            }
        }
    }

    /// Writes `bytes` at `key` whole or not at all.
    pub async fn put(&self, key: &str, bytes: bytes::Bytes) -> anyhow::Result<()> {
        match self {
            ExportTarget::Directory(dir) => {
                let path = dir.join(key);
                write_whole(&path, &bytes).map_err(|e| {
                    anyhow::anyhow!("--out {}: writing {}: {e}", dir.display(), path.display())
                })
            }
            ExportTarget::Objects { store, prefix, url } => {
                store
                    .put(&object_key(prefix, key), bytes.into())
                    .await
                    .map_err(|e| anyhow::anyhow!("--out {url}: {key}: {e}"))?;
                Ok(())
            }
        }
    }

    /// Bytes of every file of the tree.
    pub async fn bytes(&self) -> anyhow::Result<u64> {
        match self {
            ExportTarget::Directory(dir) => Ok(tree_bytes(dir)?),
            ExportTarget::Objects { store, prefix, url } => {
                use futures_util::TryStreamExt;
                let objects: Vec<_> = store
                    .list(Some(prefix))
                    .try_collect()
                    .await
                    .map_err(|e| anyhow::anyhow!("--out {url}: {e}"))?;
                Ok(objects.iter().map(|o| o.size).sum())
            }
        }
    }
}

impl std::fmt::Display for ExportTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExportTarget::Directory(dir) => write!(f, "{}", dir.display()),
            ExportTarget::Objects { url, .. } => f.write_str(url),
        }
    }
}

/// The object key of the tree's file `key` under `prefix`.
fn object_key(prefix: &ObjectPath, key: &str) -> ObjectPath {
    key.split('/')
        .fold(prefix.clone(), |path, part| path.child(part))
}

/// Writes `bytes` to `path` whole or not at all: to a temporary file beside it, then renamed.
fn write_whole(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut partial = path.as_os_str().to_owned();
    partial.push(PARTIAL);
    let written = std::fs::write(&partial, bytes).and_then(|()| {
        // A file system that took fewer bytes than given without an error is refused too.
        let size = std::fs::metadata(&partial)?.len();
        if size == bytes.len() as u64 {
            Ok(())
        } else {
            Err(std::io::Error::other(format!(
                "{size} of {} bytes were written",
                bytes.len()
            )))
        }
    });
    if let Err(e) = written {
        // Nothing half written stays behind (a full disk gets its space back).
        let _ = std::fs::remove_file(&partial);
        return Err(e);
    }
    std::fs::rename(&partial, path)
}

/// Removes what an interrupted run left half written.
fn remove_partial_files(dir: &Path) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        if entry.file_type()?.is_dir() {
            remove_partial_files(&path)?;
        } else if path.to_string_lossy().ends_with(PARTIAL) {
            std::fs::remove_file(&path)?;
        }
    }
    Ok(())
}

/// Bytes of every file under `dir`.
fn tree_bytes(dir: &Path) -> std::io::Result<u64> {
    let mut total = 0;
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        total += if entry.file_type()?.is_dir() {
            tree_bytes(&entry.path())?
        } else {
            entry.metadata()?.len()
        };
    }
    Ok(total)
}

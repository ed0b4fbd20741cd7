//! The pages' npm packages under `/vendor/` (from `--assets-dir`), served only from inside
//! their folders: a path that resolves (through a symbolic link) outside its package's folder
//! is a 404, as if it were not there.

use super::error_bodies::json_error;
use axum::extract::{Request, State};
use axum::http::StatusCode;
use axum::middleware::Next;
use axum::response::Response;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

/// Serves the request only when the file it names lies inside `root` once every link is
/// followed.
pub async fn contained(State(root): State<Arc<PathBuf>>, request: Request, next: Next) -> Response {
    let decoded = percent_encoding::percent_decode_str(request.uri().path()).decode_utf8_lossy();
    let relative: PathBuf = Path::new(decoded.as_ref())
        .components()
        .filter(|c| matches!(c, Component::Normal(_)))
        .collect();
    let root_and_file = async {
        let root = tokio::fs::canonicalize(root.as_path()).await.ok()?;
        let file = tokio::fs::canonicalize(root.join(&relative)).await.ok()?;
        Some((root, file))
    };
    match root_and_file.await {
        // Inside, or not there at all (the file server answers 404 for what is missing).
        None => next.run(request).await,
        Some((root, file)) if file.starts_with(&root) => next.run(request).await,
        Some(_) => json_error(
            StatusCode::NOT_FOUND,
            "not_found",
            format!(
                "nothing is served at {}; see /docs for the API",
                request.uri().path()
            ),
        ),
    }
}

//! The one error type of the building sources.

use crate::upstream::OverpassError;

/// Why a source could not give the buildings of an area.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SourceError {
    /// The upstream (Overpass) failed, timed out or is rate limiting.
    #[error(transparent)]
    Upstream(#[from] OverpassError),
    /// The area needs more data tiles than one request may load.
    #[error(
        "the area needs {tiles} OSM data tiles, more than {max} per request: request a smaller or squarer area, or tiles"
    )]
    AreaTooLarge { tiles: usize, max: usize },
    /// The area needs more data tiles fetched than one request may fetch; the ones it fetched
    /// are kept, so asking again goes further.
    #[error(
        "the area needs more OSM data tiles from upstream than one request may fetch \
         (--overpass-calls-per-request {limit}); {limit} were fetched and kept: ask again to fetch \
         the next ones"
    )]
    CallBudget { limit: usize },
    /// The data-tile store (SQLite) failed.
    #[error("OSM data store: {0}")]
    Store(String),
    /// The data-tile store (SQLite) was too busy to answer in time.
    #[error("OSM data store busy: {0}")]
    StoreBusy(String),
    /// Stored data could not be parsed.
    #[error("stored OSM data unreadable: {0}")]
    Unreadable(String),
    /// A blocking task failed (a bug).
    #[error("source task failed: {0}")]
    Task(String),
}

impl From<sqlx::Error> for SourceError {
    fn from(e: sqlx::Error) -> Self {
        if crate::db::is_busy(&e) {
            SourceError::StoreBusy(e.to_string())
        } else {
            SourceError::Store(e.to_string())
        }
    }
}

impl From<tokio::task::JoinError> for SourceError {
    fn from(e: tokio::task::JoinError) -> Self {
        SourceError::Task(e.to_string())
    }
}

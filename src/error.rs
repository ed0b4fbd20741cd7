//! The one error type of the server. Every failure a client can see becomes a JSON body
//! `{"error": "<code>", "detail": "<what to fix>"}` with a fitting status; internal causes go to the
//! log, never to the client.

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The body of every error response.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema, PartialEq, Eq)]
pub struct ErrorBody {
    /// A stable machine-readable code, e.g. `invalid_bbox`.
    #[schema(example = "invalid_bbox")]
    pub error: String,
    /// What went wrong and how to fix the request.
    #[schema(
        example = "minLon 8.41 must be smaller than maxLon 8.39 (the order is minLon,minLat,maxLon,maxLat)"
    )]
    pub detail: String,
    /// For uploaded GeoJSON: the index of the feature at fault.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feature: Option<usize>,
    /// For uploaded GeoJSON: the field at fault, e.g. `properties.height`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

#[derive(Debug, Clone, thiserror::Error)]
pub enum AppError {
    /// The request is malformed: 400.
    #[error("{code}: {detail}")]
    BadRequest { code: &'static str, detail: String },
    /// An uploaded document cannot be used: 413 (too large), 415 (not JSON) or 422 (not valid
    /// building GeoJSON), naming the feature and field at fault.
    #[error("{code}: {detail}")]
    Document {
        status: StatusCode,
        code: &'static str,
        detail: String,
        feature: Option<usize>,
        field: Option<String>,
    },
    /// Nothing is served at this address: 404.
    #[error("{code}: {detail}")]
    NotFound { code: &'static str, detail: String },
    /// The upstream OSM source failed or sent something unusable: 502.
    #[error("upstream failed: {0}")]
    UpstreamFailed(String),
    /// The upstream OSM source is rate limiting or overloaded, or citymesh itself is at its
    /// limit of concurrent generations: 503 with `Retry-After`.
    #[error("{detail}")]
    Unavailable {
        code: &'static str,
        detail: String,
        retry_after_secs: u64,
    },
    /// The client is over its share of a resource the server bounds: 429 with `Retry-After`.
    #[error("{code}: {detail}")]
    TooMany {
        code: &'static str,
        detail: String,
        retry_after_secs: u64,
    },
    /// The upstream OSM source did not answer in time: 504.
    #[error("upstream timed out: {0}")]
    UpstreamTimeout(String),
    /// A bug or an I/O failure on our side: 500 with a generic message; the cause is logged.
    #[error("internal error: {0}")]
    Internal(String),
}

impl AppError {
    pub fn bad_request(code: &'static str, detail: impl Into<String>) -> Self {
        Self::BadRequest {
            code,
            detail: detail.into(),
        }
    }

    pub fn not_found(code: &'static str, detail: impl Into<String>) -> Self {
        Self::NotFound {
            code,
            detail: detail.into(),
        }
    }

    pub fn internal(cause: impl std::fmt::Display) -> Self {
        Self::Internal(cause.to_string())
    }
}

/// How long clients should wait after an upstream failure or timeout before asking again.
const UPSTREAM_RETRY_AFTER_SECS: u64 = 30;

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        let mut retry_after = None;
        let mut at = (None, None);
        let (status, code, detail) = match self {
            AppError::Document {
                status,
                code,
                detail,
                feature,
                field,
            } => {
                at = (feature, field);
                (status, code, detail)
            }
            AppError::BadRequest { code, detail } => (StatusCode::BAD_REQUEST, code, detail),
            AppError::NotFound { code, detail } => (StatusCode::NOT_FOUND, code, detail),
            AppError::UpstreamFailed(cause) => {
                tracing::warn!(%cause, "upstream failed");
                retry_after = Some(UPSTREAM_RETRY_AFTER_SECS);
                (
                    StatusCode::BAD_GATEWAY,
                    "upstream_failed",
                    format!("{cause}; nothing was stored, try again later"),
                )
            }
            AppError::Unavailable {
                code,
                detail,
                retry_after_secs,
            } => {
                retry_after = Some(retry_after_secs);
                (StatusCode::SERVICE_UNAVAILABLE, code, detail)
            }
            AppError::TooMany {
                code,
                detail,
                retry_after_secs,
            } => {
                retry_after = Some(retry_after_secs);
                (StatusCode::TOO_MANY_REQUESTS, code, detail)
            }
            AppError::UpstreamTimeout(cause) => {
                tracing::warn!(%cause, "upstream timed out");
                retry_after = Some(UPSTREAM_RETRY_AFTER_SECS);
                (
                    StatusCode::GATEWAY_TIMEOUT,
                    "upstream_timeout",
                    format!("{cause}; try again later"),
                )
            }
            AppError::Internal(cause) => {
                tracing::error!(%cause, "request failed");
                (
                    StatusCode::INTERNAL_SERVER_ERROR,
                    "internal",
                    "citymesh failed to answer this request; the server log has the cause"
                        .to_owned(),
                )
            }
        };
        let mut response = (
            status,
            Json(ErrorBody {
                error: code.to_owned(),
                detail,
                feature: at.0,
                field: at.1,
            }),
        )
            .into_response();
        if let Some(secs) = retry_after
            && let Ok(v) = axum::http::HeaderValue::from_str(&secs.to_string())
        {
            response
                .headers_mut()
                .insert(axum::http::header::RETRY_AFTER, v);
        }
        response
    }
}

impl From<crate::upstream::OverpassError> for AppError {
    fn from(e: crate::upstream::OverpassError) -> Self {
        use crate::upstream::OverpassError;
        match e {
            OverpassError::Busy { retry_after, .. } => AppError::Unavailable {
                code: "upstream_busy",
                detail: format!("{e}; nothing was stored, try again after the Retry-After delay"),
                retry_after_secs: retry_after
                    .map_or(UPSTREAM_RETRY_AFTER_SECS, |d| d.as_secs().max(1)),
            },
            OverpassError::HeldBack { retry_after, .. } => AppError::Unavailable {
                code: "upstream_held_back",
                detail: format!("{e}; the data already fetched is kept"),
                retry_after_secs: retry_after.as_secs().max(1),
            },
            OverpassError::Timeout(_) | OverpassError::GatewayTimeout => {
                AppError::UpstreamTimeout(e.to_string())
            }
            OverpassError::TooLarge { .. } | OverpassError::Bad(_) => {
                AppError::UpstreamFailed(e.to_string())
            }
        }
    }
}

impl From<crate::source::SourceError> for AppError {
    fn from(e: crate::source::SourceError) -> Self {
        use crate::source::SourceError;
        match e {
            SourceError::Upstream(e) => e.into(),
            SourceError::AreaTooLarge { .. } => {
                AppError::bad_request("bbox_too_large", e.to_string())
            }
            SourceError::CallBudget { .. } => AppError::Unavailable {
                code: "upstream_budget",
                detail: e.to_string(),
                retry_after_secs: 1,
            },
            SourceError::StoreBusy(_) => {
                tracing::warn!("{e}");
                AppError::Unavailable {
                    code: "database_busy",
                    detail: "the cache database is busy with other writes; try again after the \
                             Retry-After delay"
                        .to_owned(),
                    retry_after_secs: DATABASE_RETRY_AFTER_SECS,
                }
            }
            other => AppError::internal(other),
        }
    }
}

impl From<tokio::task::JoinError> for AppError {
    fn from(e: tokio::task::JoinError) -> Self {
        AppError::internal(format!("generation task failed: {e}"))
    }
}

/// Seconds a client waits before trying again when the database was busy.
const DATABASE_RETRY_AFTER_SECS: u64 = 2;

impl From<sqlx::Error> for AppError {
    fn from(e: sqlx::Error) -> Self {
        if crate::db::is_busy(&e) {
            tracing::warn!("cache database busy: {e}");
            return AppError::Unavailable {
                code: "database_busy",
                detail: "the cache database is busy with other writes; try again after the \
                         Retry-After delay"
                    .to_owned(),
                retry_after_secs: DATABASE_RETRY_AFTER_SECS,
            };
        }
        AppError::internal(format!("cache database: {e}"))
    }
}

impl From<crate::roofs::jobs::JobError> for AppError {
    fn from(e: crate::roofs::jobs::JobError) -> Self {
        match e {
            crate::roofs::jobs::JobError::Store(e) => e.into(),
            other => AppError::internal(other),
        }
    }
}

impl From<crate::pipeline::PipelineError> for AppError {
    fn from(e: crate::pipeline::PipelineError) -> Self {
        use crate::pipeline::PipelineError as P;
        let detail = e.to_string();
        let unavailable = |code: &'static str, retry_after_secs: u64| AppError::Unavailable {
            code,
            detail: detail.clone(),
            retry_after_secs,
        };
        match e {
            P::InvalidArea(_) => AppError::bad_request("invalid_tile", detail),
            P::TooComplex { .. } => AppError::bad_request("area_too_complex", detail),
            P::Timeout(_) | P::MeasureTooLong { .. } => unavailable("timeout", 5),
            P::Busy => unavailable("busy", 1),
            P::Abandoned => unavailable("cancelled", 1),
            P::ShuttingDown => unavailable("shutting_down", 5),
        }
    }
}

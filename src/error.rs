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
}

#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// The request is malformed: 400.
    #[error("{code}: {detail}")]
    BadRequest { code: &'static str, detail: String },
    /// Nothing is served at this address: 404.
    #[error("{code}: {detail}")]
    NotFound { code: &'static str, detail: String },
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

impl IntoResponse for AppError {
    fn into_response(self) -> Response {
        let (status, code, detail) = match self {
            AppError::BadRequest { code, detail } => (StatusCode::BAD_REQUEST, code, detail),
            AppError::NotFound { code, detail } => (StatusCode::NOT_FOUND, code, detail),
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
        (
            status,
            Json(ErrorBody {
                error: code.to_owned(),
                detail,
            }),
        )
            .into_response()
    }
}

impl From<tokio::task::JoinError> for AppError {
    fn from(e: tokio::task::JoinError) -> Self {
        AppError::internal(format!("generation task failed: {e}"))
    }
}

impl From<sqlx::Error> for AppError {
    fn from(e: sqlx::Error) -> Self {
        AppError::internal(format!("cache database: {e}"))
    }
}

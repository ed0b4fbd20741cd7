//! Which web pages may change state: every origin may read (tiles, scenes, 3D Tiles, statistics,
//! `POST /scene.glb`, which only computes), but only the server's own pages and the origins
//! `--cors-origin` lists may queue, cancel or adapt classification (`POST` and `DELETE` under
//! `/classify`). A browser page elsewhere gets 403 before anything runs, its preflight included.
//! Clients that send no `Origin` (curl, servers, generated clients) are not browsers' pages and
//! are not affected.

use crate::error::ErrorBody;
use crate::state::AppState;
use axum::Json;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

/// Whether the request changes state (or is the preflight of one).
fn changes_state(request: &Request) -> bool {
    if !request.uri().path().starts_with("/classify") {
        return false;
    }
    let writes = |m: &Method| *m == Method::POST || *m == Method::DELETE;
    if *request.method() == Method::OPTIONS {
        return request
            .headers()
            .get(header::ACCESS_CONTROL_REQUEST_METHOD)
            .and_then(|v| v.to_str().ok())
            .and_then(|m| m.parse::<Method>().ok())
            .is_some_and(|m| writes(&m));
    }
    writes(request.method())
}

/// Whether `origin` is the server's own (its host and port are the request's `Host`).
fn same_origin(origin: &str, headers: &HeaderMap) -> bool {
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        return false;
    };
    origin
        .split_once("://")
        .is_some_and(|(_, rest)| rest.eq_ignore_ascii_case(host))
}

/// Refuses state-changing requests from pages of origins that are neither the server's own nor
/// listed.
pub async fn guard(State(state): State<AppState>, request: Request, next: Next) -> Response {
    if changes_state(&request)
        && let Some(origin) = request
            .headers()
            .get(header::ORIGIN)
            .map(|o| o.to_str().unwrap_or("?").trim_end_matches('/').to_owned())
        && !same_origin(&origin, request.headers())
        && !state
            .cors_origins
            .iter()
            .any(|o| o.trim_end_matches('/').eq_ignore_ascii_case(&origin))
    {
        return (
            StatusCode::FORBIDDEN,
            Json(ErrorBody {
                error: "cross_origin_forbidden".into(),
                detail: format!(
                    "pages of {origin} may read from this server but not change its state; \
                     the operator can allow them with --cors-origin {origin}"
                ),
                feature: None,
                field: None,
            }),
        )
            .into_response();
    }
    next.run(request).await
}

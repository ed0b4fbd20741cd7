//! Every error a client sees has the JSON error body: answers made outside the handlers (axum's
//! 405, a static file's 404, a timed-out body's 408, ...) get one here, and over-long URIs and
//! header blocks are refused with one before anything else runs.

use crate::error::ErrorBody;
use axum::Json;
use axum::extract::Request;
use axum::http::{HeaderMap, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

/// Longest request target accepted, bytes.
pub const MAX_URI_BYTES: usize = 8 * 1024;
/// Largest header block accepted (names and values), bytes.
pub const MAX_HEADER_BYTES: usize = 32 * 1024;
/// Most header lines accepted.
pub const MAX_HEADER_COUNT: usize = 100;

/// An error answer with the JSON body.
pub(super) fn json_error(status: StatusCode, code: &str, detail: String) -> Response {
    (
        status,
        Json(ErrorBody {
            error: code.to_owned(),
            detail,
            feature: None,
            field: None,
        }),
    )
        .into_response()
}

fn header_bytes(headers: &HeaderMap) -> usize {
    headers
        .iter()
        .map(|(k, v)| k.as_str().len() + v.len() + 4)
        .sum()
}

/// Refuses over-long requests, and gives every error answer without a JSON body one.
pub async fn json_errors(request: Request, next: Next) -> Response {
    let uri = request.uri();
    let uri_len = uri.path().len() + uri.query().map_or(0, |q| q.len() + 1);
    if uri_len > MAX_URI_BYTES {
        return json_error(
            StatusCode::URI_TOO_LONG,
            "uri_too_long",
            format!(
                "the request target has {uri_len} bytes, more than {MAX_URI_BYTES}: shorten the query"
            ),
        );
    }
    let lines = request.headers().len();
    if lines > MAX_HEADER_COUNT {
        return json_error(
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            "headers_too_large",
            format!(
                "the request has {lines} header lines, more than {MAX_HEADER_COUNT}: send fewer"
            ),
        );
    }
    let headers = header_bytes(request.headers());
    if headers > MAX_HEADER_BYTES {
        return json_error(
            StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            "headers_too_large",
            format!(
                "the request headers have {headers} bytes, more than {MAX_HEADER_BYTES}: send fewer or shorter headers"
            ),
        );
    }
    // Kept for an error's detail; cloning them does not allocate (shared bytes).
    let (method, uri) = (request.method().clone(), request.uri().clone());
    let response = next.run(request).await;
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.starts_with("application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let path = uri.path();
    let (code, detail): (std::borrow::Cow<'static, str>, String) = match status {
        StatusCode::NOT_FOUND => (
            "not_found".into(),
            format!("nothing is served at {path}; see /docs for the API"),
        ),
        StatusCode::METHOD_NOT_ALLOWED => {
            let allowed = response
                .headers()
                .get(header::ALLOW)
                .and_then(|v| v.to_str().ok())
                .unwrap_or("")
                .to_owned();
            let detail = if allowed.is_empty() {
                format!("{path} does not answer {method}; /docs lists the methods it answers")
            } else {
                format!("{path} does not answer {method}; it answers {allowed}")
            };
            ("method_not_allowed".into(), detail)
        }
        StatusCode::REQUEST_TIMEOUT => (
            "timeout".into(),
            "the request body did not arrive in time (--body-timeout-s)".to_owned(),
        ),
        StatusCode::PAYLOAD_TOO_LARGE => (
            "too_large".into(),
            "the request body is over this server's limit".to_owned(),
        ),
        StatusCode::RANGE_NOT_SATISFIABLE => (
            "range_not_satisfiable".into(),
            format!(
                "the Range header asks for bytes {path} does not have; Content-Range gives its \
                 size: ask for bytes=0-(size-1) or fewer"
            ),
        ),
        _ => (
            status_code_name(status),
            format!(
                "{} {}",
                status.as_u16(),
                status.canonical_reason().unwrap_or("error")
            ),
        ),
    };
    // Keep what the client needs (Allow, Retry-After, CORS, Content-Range); replace the body.
    let mut answer = json_error(status, &code, detail);
    for (name, value) in response.headers() {
        if name != header::CONTENT_TYPE && name != header::CONTENT_LENGTH {
            answer.headers_mut().insert(name.clone(), value.clone());
        }
    }
    answer
}

/// A status's reason as an error code (`unsupported_media_type`), `error` when it has none.
fn status_code_name(status: StatusCode) -> std::borrow::Cow<'static, str> {
    status.canonical_reason().map_or("error".into(), |r| {
        r.to_ascii_lowercase()
            .replace(|c: char| !c.is_ascii_alphanumeric(), "_")
            .into()
    })
}

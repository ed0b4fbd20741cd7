//! What a request body may cost before any handler reads it: a declared `Content-Length` over
//! the route's limit is refused at once with 413 (so `Expect: 100-continue` gets its 413, never
//! a 100), and the whole body must arrive within `--body-timeout-s` of the headers, a total
//! deadline however the bytes trickle in (408).

use super::error_bodies::json_error;
use crate::state::AppState;
use axum::body::{Body, Bytes};
use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;
use http_body::Frame;
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::time::Sleep;

/// Largest JSON body of the routes that take one (`/classify`, `/classify/adapt`): axum's
/// default, which their extractors apply too.
pub const MAX_JSON_BODY_BYTES: usize = 2 * 1024 * 1024;

/// The largest body `method path` takes, and the error code that says it was too large.
fn body_limit(state: &AppState, method: &Method, path: &str) -> (usize, &'static str) {
    if method == Method::POST && path == "/scene.glb" {
        (state.max_upload_bytes, "too_large")
    } else {
        (MAX_JSON_BODY_BYTES, "body_too_large")
    }
}

/// Refuses over-long declared bodies and puts the rest under the body deadline.
pub async fn guard(State(state): State<AppState>, request: Request, next: Next) -> Response {
    let (limit, code) = body_limit(&state, request.method(), request.uri().path());
    let declared = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    if let Some(length) = declared
        && length > limit as u64
    {
        let mut answer = json_error(
            StatusCode::PAYLOAD_TOO_LARGE,
            code,
            format!(
                "the body would have {length} bytes, more than this route takes ({limit}); send \
                 less (split the request)"
            ),
        );
        // The body was never read: do not keep the connection for whatever follows it.
        answer.headers_mut().insert(
            header::CONNECTION,
            header::HeaderValue::from_static("close"),
        );
        return answer;
    }
    // No body (most requests: tile and scene GETs): nothing to time.
    if http_body::Body::is_end_stream(request.body()) {
        return next.run(request).await;
    }
    let timeout = state.generator.limits.body_timeout;
    let expired = Arc::new(AtomicBool::new(false));
    let (parts, body) = request.into_parts();
    let body = Body::new(DeadlineBody {
        inner: body,
        deadline: Box::pin(tokio::time::sleep(timeout)),
        expired: expired.clone(),
    });
    let response = next.run(Request::from_parts(parts, body)).await;
    if expired.load(Ordering::Relaxed) {
        let mut answer = json_error(
            StatusCode::REQUEST_TIMEOUT,
            "timeout",
            format!(
                "the request body did not arrive within {} s (--body-timeout-s); send it at once",
                secs(timeout)
            ),
        );
        answer.headers_mut().insert(
            header::CONNECTION,
            header::HeaderValue::from_static("close"),
        );
        return answer;
    }
    response
}

fn secs(d: Duration) -> String {
    format!("{}", d.as_secs_f64())
}

/// The body was not all there by its deadline.
#[derive(Debug, thiserror::Error)]
#[error("the request body did not arrive in time")]
struct BodyDeadlinePassed;

/// A request body that fails once its deadline (set when the headers arrived) has passed.
struct DeadlineBody {
    inner: Body,
    deadline: Pin<Box<Sleep>>,
    expired: Arc<AtomicBool>,
}

impl http_body::Body for DeadlineBody {
    type Data = Bytes;
    type Error = axum::BoxError;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        if self.deadline.as_mut().poll(cx).is_ready() {
            self.expired.store(true, Ordering::Relaxed);
            return Poll::Ready(Some(Err(Box::new(BodyDeadlinePassed))));
        }
        Pin::new(&mut self.inner)
            .poll_frame(cx)
            .map(|frame| frame.map(|f| f.map_err(Into::into)))
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.inner.size_hint()
    }
}

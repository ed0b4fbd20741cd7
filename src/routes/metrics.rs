//! `GET /metrics`: Prometheus text format, and the middleware that counts every request.

use crate::error::ErrorBody;
use crate::metrics::CacheNameLabels;
use crate::state::AppState;
use axum::extract::{MatchedPath, Request, State};
use axum::http::{HeaderValue, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::time::Instant;

/// Counters, histograms and cache figures in the Prometheus text exposition format.
#[utoipa::path(get, path = "/metrics", tag = "service",
    responses(
        (status = 200, description = "Prometheus metrics", content_type = "text/plain", body = String),
        (status = 404, description = "Never: listed because every operation names its client errors", body = ErrorBody),
    ))]
pub async fn metrics(State(state): State<AppState>) -> Response {
    let gauges = &state.generator.metrics.memory_cache_bytes;
    for (cache, bytes) in state.memory_use().await {
        gauges
            .get_or_create(&CacheNameLabels { cache })
            .set(i64::try_from(bytes).unwrap_or(i64::MAX));
    }
    gauges
        .get_or_create(&CacheNameLabels { cache: "budget" })
        .set(i64::try_from(state.memory_budget.total).unwrap_or(i64::MAX));
    if let Some(f) = super::health::freshness(&state).await {
        let r = &state.generator.metrics.replication;
        r.sequence.set(f.sequence);
        r.lag_seconds.set(f.age_s.unwrap_or(0));
    }
    (
        [(
            header::CONTENT_TYPE,
            HeaderValue::from_static("text/plain; version=0.0.4; charset=utf-8"),
        )],
        state.generator.metrics.render(),
    )
        .into_response()
}

/// Counts the request by route (the matched pattern, so label values stay few) and status, and
/// times it.
pub async fn track(State(state): State<AppState>, request: Request, next: Next) -> Response {
    // The pattern is shared (an `Arc<str>`): holding it allocates nothing.
    let route = request.extensions().get::<MatchedPath>().cloned();
    let started = Instant::now();
    let response = next.run(request).await;
    state.generator.metrics.requests.record(
        route.as_ref().map_or("unmatched", MatchedPath::as_str),
        response.status().as_u16(),
        started.elapsed(),
    );
    response
}

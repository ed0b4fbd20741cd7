//! HTTP caching for GLB and other cacheable answers: a strong ETag, `If-None-Match` -> 304 Not Modified, and
//! `Cache-Control`.

use super::headers::glb_headers;
use crate::cache::{CacheLevel, CachedTile, etag_header};
use crate::pipeline::Generated;
use axum::body::Body;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;

/// Whether an `If-None-Match` header names this ETag (or is `*`).
fn matches(request: &HeaderMap, ours: &HeaderValue) -> bool {
    let Ok(ours) = ours.to_str() else {
        return false;
    };
    let Some(value) = request
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
    else {
        return false;
    };
    value.split(',').map(str::trim).any(|candidate| {
        candidate == "*" || candidate == ours || candidate.strip_prefix("W/") == Some(ours)
    })
}

/// The body with its headers, or 304 when the client has it already.
pub fn conditional_response(
    request: &HeaderMap,
    body: Bytes,
    etag: HeaderValue,
    mut headers: HeaderMap,
    cache_control: &'static str,
) -> Response {
    let not_modified = matches(request, &etag);
    headers.insert(header::ETAG, etag);
    headers.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static(cache_control),
    );
    if not_modified {
        headers.remove(header::CONTENT_TYPE);
        return (StatusCode::NOT_MODIFIED, headers, Body::empty()).into_response();
    }
    (headers, body).into_response()
}

/// A freshly generated GLB, with its figures in the headers.
pub fn generated_response(
    request: &HeaderMap,
    generated: Generated,
    cache_control: &'static str,
) -> Response {
    let etag = etag_header(None, &generated.glb);
    let mut headers = glb_headers(Some(&generated.stats));
    headers.insert(
        axum::http::HeaderName::from_static("x-citymesh-cache"),
        HeaderValue::from_static(if generated.from_cache { "hit" } else { "miss" }),
    );
    conditional_response(request, generated.glb, etag, headers, cache_control)
}

/// A tile from the tile cache, saying which level it came from.
pub fn cached_response(
    request: &HeaderMap,
    cached: CachedTile,
    level: CacheLevel,
    cache_control: &'static str,
) -> Response {
    let mut headers = glb_headers(cached.generated.as_deref());
    headers.insert(
        axum::http::HeaderName::from_static("x-citymesh-cache"),
        HeaderValue::from_static(level.name()),
    );
    conditional_response(request, cached.bytes, cached.etag, headers, cache_control)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_lists_and_wildcards() {
        let etag = &HeaderValue::from_static("\"abc\"");
        let mut h = HeaderMap::new();
        assert!(!matches(&h, etag));
        h.insert(
            header::IF_NONE_MATCH,
            HeaderValue::from_static("\"x\", \"abc\""),
        );
        assert!(matches(&h, etag));
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("*"));
        assert!(matches(&h, etag));
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("\"abd\""));
        assert!(!matches(&h, etag));
    }
}

//! HTTP caching for GLB and other cacheable answers: a strong ETag, `If-None-Match` -> 304 Not Modified, and
//! `Cache-Control`.

use super::headers::glb_headers;
use crate::cache::{CacheLevel, CachedTile, content_coding, etag_header};
use crate::error::AppError;
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

/// A tile from the tile cache, saying which level it came from. A tile kept gzip-compressed
/// goes out so (`Content-Encoding: gzip`) when the client accepts it, else inflated, under an
/// ETag of its own (each representation has its own validator).
pub async fn cached_response(
    request: &HeaderMap,
    cached: CachedTile,
    level: CacheLevel,
    cache_control: &'static str,
) -> Result<Response, AppError> {
    let mut headers = glb_headers(cached.generated.as_deref());
    headers.insert(
        axum::http::HeaderName::from_static("x-citymesh-cache"),
        HeaderValue::from_static(level.name()),
    );
    if !content_coding::is_gzip(&cached.bytes) {
        return Ok(conditional_response(
            request,
            cached.bytes,
            cached.etag,
            headers,
            cache_control,
        ));
    }
    headers.insert(header::VARY, HeaderValue::from_static("accept-encoding"));
    let accepts = request
        .get_all(header::ACCEPT_ENCODING)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(content_coding::accepts_gzip);
    if accepts {
        headers.insert(header::CONTENT_ENCODING, HeaderValue::from_static("gzip"));
        return Ok(conditional_response(
            request,
            cached.bytes,
            cached.etag,
            headers,
            cache_control,
        ));
    }
    let etag = cached
        .etag
        .to_str()
        .ok()
        .and_then(|e| {
            HeaderValue::from_str(&format!("{}-identity\"", e.trim_end_matches('"'))).ok()
        })
        .unwrap_or(cached.etag);
    if matches(request, &etag) {
        return Ok(conditional_response(
            request,
            Bytes::new(),
            etag,
            headers,
            cache_control,
        ));
    }
    let gzipped = cached.bytes;
    let bytes = tokio::task::spawn_blocking(move || content_coding::gunzip(&gzipped))
        .await
        .map_err(AppError::from)?
        .map_err(|e| AppError::Internal(format!("a stored tile does not inflate: {e}")))?;
    Ok(conditional_response(
        request,
        bytes,
        etag,
        headers,
        cache_control,
    ))
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

//! `Accept` negotiation with quality values (RFC 9110 section 12.5.1): which of the media types a
//! route offers the client prefers.

use axum::http::{HeaderMap, header};

/// Most media ranges read from the `Accept` headers (the rest are ignored).
const MAX_RANGES: usize = 64;

/// The quality the client gives `media` (`type/subtype`, lower case): the most specific range
/// that matches it decides (`type/subtype`, then `type/*`, then `*/*`); 0 when none matches.
/// Without an `Accept` header every type has quality 1.
pub fn quality(headers: &HeaderMap, media: &str) -> f32 {
    let (kind, _) = media.split_once('/').unwrap_or((media, ""));
    let mut best: Option<(u8, f32)> = None;
    let mut any = false;
    let ranges = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .take(MAX_RANGES);
    for range in ranges {
        let mut parts = range.split(';');
        let name = parts.next().unwrap_or("").trim().to_ascii_lowercase();
        if name.is_empty() {
            continue;
        }
        any = true;
        let specificity = if name == media {
            3
        } else if name.strip_suffix("/*") == Some(kind) {
            2
        } else if name == "*/*" {
            1
        } else {
            continue;
        };
        let q = parts
            .filter_map(|p| p.trim().strip_prefix("q=").or(p.trim().strip_prefix("Q=")))
            .map(|v| {
                v.trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|q| (0.0..=1.0).contains(q))
            })
            .next()
            .unwrap_or(Some(1.0))
            .unwrap_or(0.0);
        if best.is_none_or(|(s, _)| specificity > s) {
            best = Some((specificity, q));
        }
    }
    match best {
        Some((_, q)) => q,
        None if any => 0.0,
        None => 1.0,
    }
}

/// Whether the client prefers `a` to `b` (strictly: on a tie, `b`).
pub fn prefers(headers: &HeaderMap, a: &str, b: &str) -> bool {
    quality(headers, a) > quality(headers, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn accept(v: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(header::ACCEPT, HeaderValue::from_str(v).unwrap());
        h
    }

    const JSON: &str = "application/json";
    const GLB: &str = "model/gltf-binary";

    #[test]
    fn quality_values_decide_and_ties_keep_the_default() {
        assert!(prefers(&accept(JSON), JSON, GLB));
        assert!(prefers(
            &accept("model/gltf-binary;q=0.5, application/json"),
            JSON,
            GLB
        ));
        assert!(!prefers(
            &accept("application/json;q=0.4, model/gltf-binary;q=0.9"),
            JSON,
            GLB
        ));
        assert!(!prefers(&accept("*/*"), JSON, GLB));
        assert!(!prefers(&HeaderMap::new(), JSON, GLB));
        assert!(!prefers(&accept("application/json;q=0, */*"), JSON, GLB));
        assert!(prefers(&accept("application/*, model/*;q=0.2"), JSON, GLB));
        // The most specific range decides: JSON excluded even though */* allows all.
        assert_eq!(quality(&accept("*/*, application/json;q=0"), JSON), 0.0);
        assert_eq!(quality(&accept("text/html"), JSON), 0.0);
        // A malformed q counts as 0, not as a preference.
        assert_eq!(quality(&accept("application/json;q=high"), JSON), 0.0);
        assert_eq!(quality(&accept("application/json; q=0.7"), JSON), 0.7);
    }
}

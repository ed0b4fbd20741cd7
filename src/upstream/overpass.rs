//! The Overpass API client: asks for the `building` and `building:part` ways and relations of
//! one box, with a timeout, retries with backoff on 429, 5xx and timeouts (honouring
//! `Retry-After`), a descriptive User-Agent, and a cap on requests in flight. A response is only
//! handed back when it is complete, valid Overpass JSON: a failed or truncated answer is never
//! stored as data.

use citymesh_core::geo::GeoBbox;
use reqwest::StatusCode;
use std::time::Duration;
use tokio::sync::Semaphore;

/// The public main instance.
pub const DEFAULT_OVERPASS_URL: &str = "https://overpass-api.de/api/interpreter";

/// Longest wait between retries, whatever `Retry-After` says.
const MAX_BACKOFF: Duration = Duration::from_secs(30);

/// How the client behaves.
#[derive(Debug, Clone)]
pub struct OverpassConfig {
    /// Endpoints, tried in turn on each retry.
    pub urls: Vec<String>,
    /// Time for one whole request, headers and body.
    pub timeout: Duration,
    /// Retries after the first attempt.
    pub retries: u32,
    /// First backoff; doubles on each retry.
    pub backoff: Duration,
    /// Requests in flight at most.
    pub max_concurrent: usize,
}

/// Why Overpass gave no data. Each maps to the status a client of citymesh sees.
#[derive(Debug, Clone, thiserror::Error)]
pub enum OverpassError {
    /// Overpass asked us to slow down (429) or is overloaded (503): answer 503.
    #[error("Overpass is rate limiting or overloaded (HTTP {status})")]
    Busy {
        status: u16,
        retry_after: Option<Duration>,
    },
    /// No complete answer in time: answer 504.
    #[error("Overpass did not answer within {0:?}")]
    Timeout(Duration),
    /// An error status, a broken connection, or a body that is not complete Overpass JSON:
    /// answer 502.
    #[error("Overpass failed: {0}")]
    Bad(String),
}

impl OverpassError {
    /// A stable short name for metrics.
    pub fn kind(&self) -> &'static str {
        match self {
            OverpassError::Busy { .. } => "busy",
            OverpassError::Timeout(_) => "timeout",
            OverpassError::Bad(_) => "bad_response",
        }
    }
}

pub struct OverpassClient {
    http: reqwest::Client,
    config: OverpassConfig,
    permits: Semaphore,
}

/// The Overpass QL query for the buildings of a box.
pub fn building_query(bbox: &GeoBbox, timeout: Duration) -> String {
    let b = format!(
        "{},{},{},{}",
        bbox.min_lat(),
        bbox.min_lon(),
        bbox.max_lat(),
        bbox.max_lon()
    );
    format!(
        "[out:json][timeout:{}];(way[\"building\"]({b});way[\"building:part\"]({b});\
         relation[\"building\"][\"type\"=\"multipolygon\"]({b});\
         relation[\"building:part\"][\"type\"=\"multipolygon\"]({b}););out body;>;out skel qt;",
        timeout.as_secs().max(1)
    )
}

impl OverpassClient {
    pub fn new(config: OverpassConfig) -> anyhow::Result<Self> {
        let http = reqwest::Client::builder()
            .user_agent(concat!(
                "citymesh/",
                env!("CARGO_PKG_VERSION"),
                " (3D city meshes from OpenStreetMap; +https://github.com/citymesh)"
            ))
            .timeout(config.timeout)
            .connect_timeout(config.timeout.min(Duration::from_secs(10)))
            .build()?;
        Ok(Self {
            http,
            permits: Semaphore::new(config.max_concurrent.max(1)),
            config,
        })
    }

    /// The raw Overpass JSON of the buildings in `bbox`, checked to be complete.
    pub async fn fetch_buildings(&self, bbox: &GeoBbox) -> Result<Vec<u8>, OverpassError> {
        let query = building_query(bbox, self.config.timeout);
        let mut backoff = self.config.backoff;
        let mut attempt = 0u32;
        loop {
            let url = &self.config.urls[attempt as usize % self.config.urls.len()];
            let result = {
                let _permit = self
                    .permits
                    .acquire()
                    .await
                    .map_err(|e| OverpassError::Bad(e.to_string()))?;
                self.once(url, &query).await
            };
            let error = match result {
                Ok(body) => return Ok(body),
                Err(e) => e,
            };
            let retry = matches!(
                error,
                OverpassError::Busy { .. } | OverpassError::Timeout(_)
            ) || matches!(&error, OverpassError::Bad(m) if m.starts_with("HTTP 5"));
            if !retry || attempt >= self.config.retries {
                return Err(error);
            }
            let wait = match &error {
                OverpassError::Busy {
                    retry_after: Some(d),
                    ..
                } => (*d).min(MAX_BACKOFF),
                _ => backoff.min(MAX_BACKOFF),
            };
            tracing::warn!(%error, attempt, ?wait, "Overpass request failed; retrying");
            tokio::time::sleep(wait).await;
            backoff *= 2;
            attempt += 1;
        }
    }

    async fn once(&self, url: &str, query: &str) -> Result<Vec<u8>, OverpassError> {
        let timeout = self.config.timeout;
        let classify = |e: reqwest::Error| {
            if e.is_timeout() {
                OverpassError::Timeout(timeout)
            } else {
                OverpassError::Bad(format!("{url}: {e}"))
            }
        };
        let response = self
            .http
            .post(url)
            .form(&[("data", query)])
            .send()
            .await
            .map_err(classify)?;
        let status = response.status();
        if status == StatusCode::TOO_MANY_REQUESTS || status == StatusCode::SERVICE_UNAVAILABLE {
            let retry_after = response
                .headers()
                .get(reqwest::header::RETRY_AFTER)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.trim().parse::<u64>().ok())
                .map(Duration::from_secs);
            return Err(OverpassError::Busy {
                status: status.as_u16(),
                retry_after,
            });
        }
        if status == StatusCode::GATEWAY_TIMEOUT {
            return Err(OverpassError::Timeout(timeout));
        }
        if !status.is_success() {
            return Err(OverpassError::Bad(format!("HTTP {}", status.as_u16())));
        }
        let body = response.bytes().await.map_err(classify)?;
        check_complete(&body)?;
        Ok(body.to_vec())
    }
}

/// Accepts only a whole JSON document with an `elements` array and no runtime error remark
/// (Overpass reports timeouts and memory exhaustion inside a 200 answer).
pub fn check_complete(body: &[u8]) -> Result<(), OverpassError> {
    #[derive(serde::Deserialize)]
    struct Shape {
        #[serde(rename = "elements")]
        _elements: serde::de::IgnoredAny,
        #[serde(default)]
        remark: Option<String>,
    }
    let shape: Shape = serde_json::from_slice(body).map_err(|e| {
        OverpassError::Bad(format!(
            "the answer is not complete Overpass JSON ({e}, {} bytes)",
            body.len()
        ))
    })?;
    if let Some(remark) = shape.remark.filter(|r| r.contains("error")) {
        return Err(OverpassError::Bad(format!("Overpass reported: {remark}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_query_asks_for_buildings_and_parts_of_the_box() {
        let b = GeoBbox::new(8.38, 49.03, 8.40, 49.05).unwrap();
        let q = building_query(&b, Duration::from_secs(25));
        assert!(q.starts_with("[out:json][timeout:25];"));
        assert!(q.contains("way[\"building\"](49.03,8.38,49.05,8.4)"));
        assert!(q.contains("relation[\"building:part\"][\"type\"=\"multipolygon\"]"));
        assert!(q.ends_with("out body;>;out skel qt;"));
    }

    #[test]
    fn truncated_and_failed_answers_are_refused() {
        assert!(check_complete(br#"{"elements": []}"#).is_ok());
        assert!(check_complete(br#"{"elements": [{"type": "node""#).is_err());
        assert!(
            check_complete(br#"{"remark": "runtime error: Query timed out", "elements": []}"#)
                .is_err()
        );
        assert!(check_complete(b"<html>502 Bad Gateway</html>").is_err());
    }
}

//! The Overpass API client: asks for the `building` and `building:part` ways and relations of
//! one box, with a timeout, retries with backoff on 5xx and timeouts, a descriptive User-Agent,
//! a cap on requests in flight and on calls per minute (all requests together). A 429 or 503
//! is not retried: every call stops until its `Retry-After` has passed (60 s when it names
//! none), across requests, and they answer 503 at once meanwhile. A response is only handed
//! back when it is complete, valid Overpass JSON: a failed or truncated answer is never stored
//! as data.

use crate::clock::Clock;
use citymesh_core::geo::GeoBbox;
use reqwest::StatusCode;
use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::Duration;
use tokio::sync::Semaphore;

/// The public main instance.
pub const DEFAULT_OVERPASS_URL: &str = "https://overpass-api.de/api/interpreter";

/// Longest wait between retries, whatever `Retry-After` says.
const MAX_BACKOFF: Duration = Duration::from_secs(30);

/// Longest `Retry-After` taken from upstream (and so passed on to clients).
pub const MAX_RETRY_AFTER: Duration = Duration::from_secs(120);

/// How long calls stop after a 429 or 503 that names no `Retry-After`.
const DEFAULT_BACKOFF_AFTER_BUSY: Duration = Duration::from_secs(60);

/// The window of `calls_per_minute`.
const MINUTE: Duration = Duration::from_secs(60);

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
    /// Largest answer accepted, bytes.
    pub max_bytes: u64,
    /// Calls (attempts, retries included) started in any minute at most, by all requests.
    pub calls_per_minute: usize,
}

/// Why Overpass gave no data. Each maps to the status a client of citymesh sees.
#[derive(Debug, Clone, thiserror::Error)]
pub enum OverpassError {
    /// Overpass asked us to slow down (429) or is overloaded (503): answer 503.
    #[error("the OpenStreetMap upstream is rate limiting or overloaded (HTTP {status})")]
    Busy {
        status: u16,
        retry_after: Option<Duration>,
    },
    /// This server holds back its own calls: the calls of the last minute reached
    /// `--overpass-calls-per-minute`, or upstream said 429/503 and its delay has not passed.
    /// Answer 503 with the delay.
    #[error("{reason}; try again in {} s", .retry_after.as_secs().max(1))]
    HeldBack {
        reason: String,
        retry_after: Duration,
    },
    /// No complete answer in time: answer 504.
    #[error("the OpenStreetMap upstream did not answer within {} s", .0.as_secs_f64())]
    Timeout(Duration),
    /// Upstream itself reported a gateway timeout (HTTP 504): answer 504.
    #[error("the OpenStreetMap upstream reported a gateway timeout (HTTP 504)")]
    GatewayTimeout,
    /// The answer is larger than `--overpass-max-mb`: answer 502, store nothing.
    #[error("the OpenStreetMap upstream sent more than {limit_mb} MB (--overpass-max-mb)")]
    TooLarge { limit_mb: u64 },
    /// An error status, a broken connection, or a body that is not complete Overpass JSON:
    /// answer 502.
    #[error("the OpenStreetMap upstream failed: {0}")]
    Bad(String),
}

impl OverpassError {
    /// A stable short name for metrics.
    pub fn kind(&self) -> &'static str {
        match self {
            OverpassError::Busy { .. } => "busy",
            OverpassError::HeldBack { .. } => "held_back",
            OverpassError::Timeout(_) | OverpassError::GatewayTimeout => "timeout",
            OverpassError::TooLarge { .. } => "too_large",
            OverpassError::Bad(_) => "bad_response",
        }
    }
}

pub struct OverpassClient {
    http: reqwest::Client,
    config: OverpassConfig,
    permits: Semaphore,
    /// When the calls of the last minute started.
    /// When the calls of the last minute were made (Unix ms).
    recent_calls: Mutex<VecDeque<i64>>,
    /// No call before this time, Unix ms (upstream said 429 or 503).
    paused_until: Mutex<Option<i64>>,
    /// What the allowance and the pauses are measured by (tests move a manual one).
    clock: Clock,
}

/// Milliseconds as a duration (none for a time past).
fn ms(ms: i64) -> Duration {
    Duration::from_millis(u64::try_from(ms).unwrap_or(0))
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
            recent_calls: Mutex::new(VecDeque::new()),
            paused_until: Mutex::new(None),
            clock: Clock::system(),
        })
    }

    /// The client with its allowance and pauses measured by `clock`.
    pub fn with_clock(mut self, clock: Clock) -> Self {
        self.clock = clock;
        self
    }

    /// Takes a call from this minute's allowance, or says why not and for how long.
    fn take_call(&self) -> Result<(), OverpassError> {
        let now = self.clock.now_ms();
        let minute = i64::try_from(MINUTE.as_millis()).unwrap_or(i64::MAX);
        if let Ok(paused) = self.paused_until.lock()
            && let Some(until) = *paused
            && until > now
        {
            return Err(OverpassError::HeldBack {
                reason: "the OpenStreetMap upstream asked this server to slow down (HTTP 429 or \
                         503), so it makes no call until the delay it gave has passed"
                    .to_owned(),
                retry_after: ms(until - now),
            });
        }
        let Ok(mut recent) = self.recent_calls.lock() else {
            return Ok(());
        };
        while recent
            .front()
            .is_some_and(|t| now.saturating_sub(*t) >= minute)
        {
            recent.pop_front();
        }
        if recent.len() >= self.config.calls_per_minute {
            let oldest = recent.front().copied().unwrap_or(now);
            return Err(OverpassError::HeldBack {
                reason: format!(
                    "this server makes at most {} calls a minute to the OpenStreetMap upstream \
                     (--overpass-calls-per-minute), and that many were made",
                    self.config.calls_per_minute
                ),
                retry_after: ms(minute - now.saturating_sub(oldest)),
            });
        }
        recent.push_back(now);
        Ok(())
    }

    /// Upstream said 429 or 503: no call until its delay has passed.
    fn pause(&self, retry_after: Option<Duration>) {
        let delay = retry_after.unwrap_or(DEFAULT_BACKOFF_AFTER_BUSY);
        let until = self
            .clock
            .now_ms()
            .saturating_add(i64::try_from(delay.as_millis()).unwrap_or(i64::MAX));
        if let Ok(mut paused) = self.paused_until.lock() {
            *paused = Some(paused.map_or(until, |p| p.max(until)));
        }
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
                self.take_call()?;
                self.once(url, &query).await
            };
            let error = match result {
                Ok(body) => return Ok(body),
                Err(e) => e,
            };
            if let OverpassError::Busy { retry_after, .. } = &error {
                // Not retried now: every request holds back until the delay has passed.
                self.pause(*retry_after);
                return Err(error);
            }
            let retry = matches!(
                error,
                OverpassError::Timeout(_) | OverpassError::GatewayTimeout
            ) || matches!(&error, OverpassError::Bad(m) if m.starts_with("HTTP 5"));
            if !retry || attempt >= self.config.retries {
                return Err(error);
            }
            let wait = backoff.min(MAX_BACKOFF);
            tracing::warn!(%error, attempt, ?wait, "Overpass request failed; retrying");
            tokio::time::sleep(wait).await;
            backoff *= 2;
            attempt += 1;
        }
    }

    async fn once(&self, url: &str, query: &str) -> Result<Vec<u8>, OverpassError> {
        let timeout = self.config.timeout;
        // The URL may carry a key: errors never name it.
        let classify = |e: reqwest::Error| {
            if e.is_timeout() {
                OverpassError::Timeout(timeout)
            } else {
                OverpassError::Bad(e.without_url().to_string())
            }
        };
        let mut response = self
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
                .map(|s| Duration::from_secs(s).min(MAX_RETRY_AFTER));
            return Err(OverpassError::Busy {
                status: status.as_u16(),
                retry_after,
            });
        }
        if status == StatusCode::GATEWAY_TIMEOUT {
            return Err(OverpassError::GatewayTimeout);
        }
        if !status.is_success() {
            return Err(OverpassError::Bad(format!("HTTP {}", status.as_u16())));
        }
        let limit = self.config.max_bytes;
        let too_large = OverpassError::TooLarge {
            limit_mb: limit >> 20,
        };
        if response.content_length().is_some_and(|n| n > limit) {
            return Err(too_large);
        }
        // Counted while streaming: a lying or missing Content-Length cannot get past the limit.
        let mut body = Vec::new();
        while let Some(chunk) = response.chunk().await.map_err(classify)? {
            if body.len() as u64 + chunk.len() as u64 > limit {
                return Err(too_large);
            }
            body.extend_from_slice(&chunk);
        }
        check_complete(&body)?;
        Ok(body)
    }
}

/// Accepts only a whole JSON document with an `elements` array, no runtime error remark
/// (Overpass reports timeouts and memory exhaustion inside a 200 answer), and every way a
/// relation names and every node a way names present (`out body; >; out skel qt;` sends them all;
/// a gap means the answer was cut).
pub fn check_complete(body: &[u8]) -> Result<(), OverpassError> {
    #[derive(serde::Deserialize)]
    struct Member {
        #[serde(rename = "type")]
        kind: String,
        #[serde(rename = "ref")]
        id: i64,
    }
    #[derive(serde::Deserialize)]
    struct Element {
        #[serde(rename = "type")]
        kind: String,
        id: i64,
        #[serde(default)]
        nodes: Vec<i64>,
        #[serde(default)]
        members: Vec<Member>,
    }
    #[derive(serde::Deserialize)]
    struct Shape {
        elements: Vec<Element>,
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
    let ids = |kind: &str| -> std::collections::HashSet<i64> {
        shape
            .elements
            .iter()
            .filter(|e| e.kind == kind)
            .map(|e| e.id)
            .collect()
    };
    let (nodes, ways) = (ids("node"), ids("way"));
    for e in &shape.elements {
        let missing = match e.kind.as_str() {
            "way" => e
                .nodes
                .iter()
                .find(|n| !nodes.contains(n))
                .map(|n| format!("node {n}")),
            "relation" => e
                .members
                .iter()
                .find(|m| m.kind == "way" && !ways.contains(&m.id))
                .map(|m| format!("way {}", m.id)),
            _ => None,
        };
        if let Some(what) = missing {
            return Err(OverpassError::Bad(format!(
                "the answer is incomplete: {} {} names {what}, which it does not contain",
                e.kind, e.id
            )));
        }
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
        // A relation whose member way is missing, a way whose node is missing.
        let relation = br#"{"elements": [{"type": "relation", "id": 5, "members":
            [{"type": "way", "ref": 7, "role": "outer"}]}]}"#;
        let e = check_complete(relation).unwrap_err().to_string();
        assert!(e.contains("relation 5 names way 7"), "{e}");
        let way = br#"{"elements": [{"type": "node", "id": 1, "lat": 0, "lon": 0},
            {"type": "way", "id": 7, "nodes": [1, 2, 1]}]}"#;
        let e = check_complete(way).unwrap_err().to_string();
        assert!(e.contains("way 7 names node 2"), "{e}");
    }
}

//! A replication feed, as OpenStreetMap (minutely, hourly, daily) and Geofabrik (per region)
//! publish them: `BASE/state.txt` names the newest sequence number and its time, and each
//! sequence `N` is `BASE/AAA/BBB/CCC.osc.gz` (`N` in nine digits, three by three) with its own
//! `AAA/BBB/CCC.state.txt`. [`catch_up`] applies every sequence after the stored one, in order,
//! each in its own transaction; [`follow`] does it again and again, backing off after errors.

use super::apply::{ApplyError, DiffReport, apply_change};
use crate::cache::TileStore;
use crate::source::data_tiles::{OsmTileStore, ReplicationState};
use citymesh_core::osm::{OsmChange, read_change};
use std::io::Read;
use std::time::Duration;

/// The largest change file taken (compressed). A minutely diff is a few hundred kB, a daily
/// one of the planet about 100 MB.
pub const MAX_CHANGE_BYTES: u64 = 512 << 20;
/// How much larger than the compressed file its contents may be.
pub const MAX_CHANGE_RATIO: u64 = 100;
/// How long one request to the feed may take.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(120);

/// Why the feed could not be followed (the store is as it was after the last diff applied).
#[derive(Debug, thiserror::Error)]
pub enum FeedError {
    #[error("{url}: {what}")]
    Upstream { url: String, what: String },
    #[error("{url}: not a replication state ({what})")]
    BadState { url: String, what: String },
    #[error(
        "{url} names sequence {remote}, behind the {stored} this store applied: is this the \
         feed the data follows?"
    )]
    Behind {
        url: String,
        remote: i64,
        stored: i64,
    },
    #[error(
        "the store has applied no diff yet: say where to start with --from-sequence N (the \
         first sequence after the imported data's time)"
    )]
    NoStart,
    #[error("{url}: {source}")]
    Change {
        url: String,
        source: citymesh_core::osm::OsmError,
    },
    #[error("sequence {sequence} ({url}): {source}")]
    Apply {
        sequence: i64,
        url: String,
        source: ApplyError,
    },
    #[error("the database: {0}")]
    Database(#[from] sqlx::Error),
}

/// What a `state.txt` says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FeedState {
    pub sequence: i64,
    pub timestamp: String,
}

/// Reads a `state.txt` (Java properties: `sequenceNumber=N`, `timestamp=...` with `\:`).
pub fn parse_state(text: &str) -> Result<FeedState, String> {
    let mut sequence = None;
    let mut timestamp = None;
    for line in text.lines().map(str::trim) {
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        if let Some((k, v)) = line.split_once('=') {
            match k.trim() {
                "sequenceNumber" => {
                    let n: i64 = v
                        .trim()
                        .parse()
                        .map_err(|_| format!("sequenceNumber={} is not a number", v.trim()))?;
                    if n < 0 {
                        return Err(format!("sequenceNumber={n} is negative"));
                    }
                    sequence = Some(n);
                }
                "timestamp" => {
                    let t = v.trim().replace("\\:", ":");
                    if chrono_like(&t) {
                        timestamp = Some(t);
                    } else {
                        return Err(format!("timestamp={t} is not an ISO 8601 UTC time"));
                    }
                }
                _ => {}
            }
        }
    }
    Ok(FeedState {
        sequence: sequence.ok_or("no sequenceNumber")?,
        timestamp: timestamp.ok_or("no timestamp")?,
    })
}

/// `YYYY-MM-DDTHH:MM:SSZ`.
fn chrono_like(t: &str) -> bool {
    let b = t.as_bytes();
    b.len() == 20
        && b.iter().enumerate().all(|(i, c)| match i {
            4 | 7 => *c == b'-',
            10 => *c == b'T',
            13 | 16 => *c == b':',
            19 => *c == b'Z',
            _ => c.is_ascii_digit(),
        })
}

/// Unix seconds of a `YYYY-MM-DDTHH:MM:SSZ` time (days from the civil calendar).
pub fn unix_seconds(t: &str) -> Option<i64> {
    if !chrono_like(t) {
        return None;
    }
    let n = |a: usize, b: usize| t[a..b].parse::<i64>().ok();
    let (y, m, d) = (n(0, 4)?, n(5, 7)?, n(8, 10)?);
    let (hh, mm, ss) = (n(11, 13)?, n(14, 16)?, n(17, 19)?);
    let (y, m) = if m <= 2 { (y - 1, m + 9) } else { (y, m - 3) };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * m + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    Some(days * 86_400 + hh * 3600 + mm * 60 + ss)
}

/// The path of sequence `n` under the feed's base: `AAA/BBB/CCC`.
pub fn sequence_path(n: i64) -> String {
    format!(
        "{:03}/{:03}/{:03}",
        n / 1_000_000,
        (n / 1_000) % 1_000,
        n % 1_000
    )
}

/// A feed at a base URL.
#[derive(Clone)]
pub struct Feed {
    base: String,
    client: reqwest::Client,
}

impl Feed {
    pub fn new(base: &str) -> Result<Self, FeedError> {
        let client = reqwest::Client::builder()
            .timeout(REQUEST_TIMEOUT)
            .user_agent(concat!("citymesh/", env!("CARGO_PKG_VERSION")))
            .build()
            .map_err(|e| FeedError::Upstream {
                url: base.to_owned(),
                what: e.to_string(),
            })?;
        Ok(Self {
            base: base.trim_end_matches('/').to_owned(),
            client,
        })
    }

    pub fn base(&self) -> &str {
        &self.base
    }

    /// A file of the feed, at most `cap` bytes.
    async fn get(&self, path: &str, cap: u64) -> Result<Vec<u8>, FeedError> {
        let url = format!("{}/{path}", self.base);
        let upstream = |what: String| FeedError::Upstream {
            url: url.clone(),
            what,
        };
        let mut response = self
            .client
            .get(&url)
            .send()
            .await
            .map_err(|e| upstream(format!("cannot be reached ({e})")))?;
        let status = response.status();
        if !status.is_success() {
            return Err(upstream(format!("answered HTTP {}", status.as_u16())));
        }
        let mut body = Vec::new();
        while let Some(chunk) = response
            .chunk()
            .await
            .map_err(|e| upstream(format!("broke off ({e})")))?
        {
            body.extend_from_slice(&chunk);
            if body.len() as u64 > cap {
                return Err(upstream(format!("is larger than {cap} bytes")));
            }
        }
        Ok(body)
    }

    /// The newest state (`state.txt`).
    pub async fn state(&self) -> Result<FeedState, FeedError> {
        self.state_at("state.txt").await
    }

    async fn state_at(&self, path: &str) -> Result<FeedState, FeedError> {
        let body = self.get(path, 64 << 10).await?;
        let text = String::from_utf8_lossy(&body);
        parse_state(&text).map_err(|what| FeedError::BadState {
            url: format!("{}/{path}", self.base),
            what,
        })
    }

    /// Sequence `n`: its state (which must name `n`) and its change file, read whole.
    pub async fn sequence(&self, n: i64) -> Result<(FeedState, OsmChange), FeedError> {
        let path = sequence_path(n);
        let state = self.state_at(&format!("{path}.state.txt")).await?;
        if state.sequence != n {
            return Err(FeedError::BadState {
                url: format!("{}/{path}.state.txt", self.base),
                what: format!("it names sequence {}, not {n}", state.sequence),
            });
        }
        let url = format!("{}/{path}.osc.gz", self.base);
        let gz = self
            .get(&format!("{path}.osc.gz"), MAX_CHANGE_BYTES)
            .await?;
        let change = tokio::task::spawn_blocking(move || read_change_file(&gz))
            .await
            .map_err(|e| FeedError::Upstream {
                url: url.clone(),
                what: e.to_string(),
            })?
            .map_err(|source| FeedError::Change {
                url: url.clone(),
                source,
            })?;
        Ok((state, change))
    }
}

/// A change file's bytes, gzipped or not, read as osmChange (at most [`MAX_CHANGE_RATIO`]
/// times larger unzipped).
pub fn read_change_file(bytes: &[u8]) -> Result<OsmChange, citymesh_core::osm::OsmError> {
    use citymesh_core::osm::OsmError;
    if bytes.starts_with(&[0x1f, 0x8b]) {
        let cap = (bytes.len() as u64)
            .saturating_mul(MAX_CHANGE_RATIO)
            .max(1 << 20);
        let mut out = Vec::new();
        flate2::read::MultiGzDecoder::new(bytes)
            .take(cap + 1)
            .read_to_end(&mut out)
            .map_err(|e| OsmError::Xml(format!("the gzip stream is broken ({e})")))?;
        if out.len() as u64 > cap {
            return Err(OsmError::Xml(format!(
                "unzips to more than {MAX_CHANGE_RATIO} times its size"
            )));
        }
        read_change(&out)
    } else {
        read_change(bytes)
    }
}

/// Applies every sequence after the stored one up to the feed's newest; `from` is the first
/// sequence when the store has applied none. Answers what each diff did.
pub async fn catch_up(
    store: &OsmTileStore,
    tiles: &TileStore,
    feed: &Feed,
    from: Option<i64>,
    mut on_diff: impl FnMut(&DiffReport),
) -> Result<Vec<DiffReport>, FeedError> {
    // Content a crash left stale is dropped first.
    super::apply::drop_pending(store, tiles).await?;
    let remote = feed.state().await?;
    let next = match store.replication_state().await? {
        Some(s) => {
            if remote.sequence < s.sequence {
                return Err(FeedError::Behind {
                    url: format!("{}/state.txt", feed.base),
                    remote: remote.sequence,
                    stored: s.sequence,
                });
            }
            s.sequence + 1
        }
        None => from.ok_or(FeedError::NoStart)?,
    };
    let mut reports = Vec::new();
    for n in next..=remote.sequence {
        let (state, change) = feed.sequence(n).await?;
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs() as i64);
        let record = ReplicationState {
            sequence: n,
            timestamp: state.timestamp,
            url: feed.base.clone(),
            applied_at: now,
        };
        let applied = apply_change(store, tiles, change, Some(record))
            .await
            .map_err(|source| FeedError::Apply {
                sequence: n,
                url: format!("{}/{}.osc.gz", feed.base, sequence_path(n)),
                source,
            })?;
        if let Some(r) = applied {
            on_diff(&r);
            reports.push(r);
        }
    }
    Ok(reports)
}

/// How [`follow`] waits.
#[derive(Debug, Clone, Copy)]
pub struct FollowTiming {
    /// Between checks of `state.txt` when caught up.
    pub interval: Duration,
    /// The longest wait after errors (the first is a second, doubling).
    pub max_backoff: Duration,
}

/// Catches up again and again for as long as the task runs: after an error the store stays
/// as it was after the last good diff (the server keeps serving it), and the next try waits
/// twice as long as the last, up to `max_backoff`.
pub async fn follow(
    store: OsmTileStore,
    tiles: TileStore,
    feed: Feed,
    from: Option<i64>,
    timing: FollowTiming,
    mut on_diff: impl FnMut(&DiffReport) + Send,
    mut on_error: impl FnMut(&FeedError) + Send,
) {
    let mut backoff = Duration::from_secs(1);
    loop {
        match catch_up(&store, &tiles, &feed, from, &mut on_diff).await {
            Ok(_) => {
                backoff = Duration::from_secs(1);
                tokio::time::sleep(timing.interval).await;
            }
            Err(e) => {
                tracing::warn!(
                    feed = feed.base(),
                    retry_in_s = backoff.as_secs(),
                    "replication: {e}"
                );
                on_error(&e);
                tokio::time::sleep(backoff.min(timing.max_backoff)).await;
                backoff = (backoff * 2).min(timing.max_backoff.max(Duration::from_secs(1)));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_paths_and_times_read_as_the_feeds_write_them() {
        let s = parse_state(
            "#Sat Dec 05 10:00:02 UTC 2026\nsequenceNumber=6123456\ntimestamp=2026-12-05T10\\:00\\:00Z\n",
        )
        .unwrap();
        assert_eq!(s.sequence, 6_123_456);
        assert_eq!(s.timestamp, "2026-12-05T10:00:00Z");
        assert_eq!(sequence_path(6_123_456), "006/123/456");
        assert_eq!(sequence_path(7), "000/000/007");
        assert_eq!(unix_seconds("1970-01-01T00:00:00Z"), Some(0));
        assert_eq!(unix_seconds("2026-12-05T10:00:00Z"), Some(1_796_464_800));
        assert!(parse_state("sequenceNumber=x\ntimestamp=2026-12-05T10:00:00Z").is_err());
        assert!(parse_state("sequenceNumber=5\ntimestamp=yesterday").is_err());
        assert!(parse_state("timestamp=2026-12-05T10:00:00Z").is_err());
    }
}

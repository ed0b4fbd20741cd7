//! Requests by route and status, and their latency by route: plain atomics per route, so
//! counting a request takes no lock and allocates nothing (a cached tile is answered in a few
//! microseconds, and this runs for every request). Rendered through the registry as
//! `citymesh_http_requests_total` and `citymesh_http_request_duration_seconds`.

use super::{RequestLabels, RouteLabels, latency_buckets};
use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric, NoLabelSet};
use prometheus_client::metrics::MetricType;
use prometheus_client::metrics::counter::ConstCounter;
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};
use std::time::Duration;

/// Status codes counted one by one: 100 to 599 (a code outside, which hyper never sends, is
/// counted at the nearer end).
const FIRST_STATUS: u16 = 100;
const STATUSES: usize = 500;

/// The upper bounds of the latency buckets, seconds.
fn bounds() -> Vec<f64> {
    latency_buckets().collect()
}

/// One route's figures.
struct RouteStats {
    by_status: Box<[AtomicU64]>,
    /// Requests per latency bucket (not cumulative); the last is above every bound.
    buckets: Box<[AtomicU64]>,
    nanos: AtomicU64,
}

impl RouteStats {
    fn new(buckets: usize) -> Self {
        Self {
            by_status: (0..STATUSES).map(|_| AtomicU64::new(0)).collect(),
            buckets: (0..=buckets).map(|_| AtomicU64::new(0)).collect(),
            nanos: AtomicU64::new(0),
        }
    }
}

/// Requests by route (the matched pattern, so the routes are few) and status.
#[derive(Debug)]
pub struct RequestMetrics {
    bounds: Vec<f64>,
    routes: RwLock<HashMap<Arc<str>, Arc<RouteStats>>>,
}

impl std::fmt::Debug for RouteStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RouteStats").finish_non_exhaustive()
    }
}

impl Default for RequestMetrics {
    fn default() -> Self {
        Self {
            bounds: bounds(),
            routes: RwLock::default(),
        }
    }
}

impl RequestMetrics {
    fn stats(&self, route: &str) -> Arc<RouteStats> {
        if let Some(s) = self
            .routes
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .get(route)
        {
            return s.clone();
        }
        self.routes
            .write()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .entry(Arc::from(route))
            .or_insert_with(|| Arc::new(RouteStats::new(self.bounds.len())))
            .clone()
    }

    /// Counts one answered request.
    pub fn record(&self, route: &str, status: u16, took: Duration) {
        let stats = self.stats(route);
        let slot = usize::from(
            status.clamp(FIRST_STATUS, FIRST_STATUS + STATUSES as u16 - 1) - FIRST_STATUS,
        );
        stats.by_status[slot].fetch_add(1, Ordering::Relaxed);
        let seconds = took.as_secs_f64();
        let bucket = self
            .bounds
            .iter()
            .position(|&b| seconds <= b)
            .unwrap_or(self.bounds.len());
        stats.buckets[bucket].fetch_add(1, Ordering::Relaxed);
        let nanos = u64::try_from(took.as_nanos()).unwrap_or(u64::MAX);
        stats.nanos.fetch_add(nanos, Ordering::Relaxed);
    }

    /// The routes seen, sorted, with their figures (a snapshot).
    fn snapshot(&self) -> Vec<(Arc<str>, Arc<RouteStats>)> {
        let mut routes: Vec<_> = self
            .routes
            .read()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        routes.sort_by(|a, b| a.0.cmp(&b.0));
        routes
    }
}

impl Collector for RequestMetrics {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let routes = self.snapshot();
        let mut family = encoder.encode_descriptor(
            "http_requests",
            "HTTP requests by route and status",
            None,
            MetricType::Counter,
        )?;
        for (route, stats) in &routes {
            for (slot, count) in stats.by_status.iter().enumerate() {
                let count = count.load(Ordering::Relaxed);
                if count == 0 {
                    continue;
                }
                let labels = RequestLabels {
                    route: route.to_string(),
                    status: FIRST_STATUS + slot as u16,
                };
                ConstCounter::new(count).encode(family.encode_family(&labels)?)?;
            }
        }
        let mut family = encoder.encode_descriptor(
            "http_request_duration_seconds",
            "Time to answer an HTTP request, by route",
            None,
            MetricType::Histogram,
        )?;
        for (route, stats) in &routes {
            let counts: Vec<u64> = stats
                .buckets
                .iter()
                .map(|c| c.load(Ordering::Relaxed))
                .collect();
            let buckets: Vec<(f64, u64)> = self
                .bounds
                .iter()
                .copied()
                .chain([f64::INFINITY])
                .zip(counts.iter().copied())
                .collect();
            let count = counts.iter().sum();
            let sum = stats.nanos.load(Ordering::Relaxed) as f64 / 1e9;
            let labels = RouteLabels {
                route: route.to_string(),
            };
            family
                .encode_family(&labels)?
                .encode_histogram::<NoLabelSet>(sum, count, &buckets, None)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prometheus_client::registry::Registry;

    fn rendered(m: RequestMetrics) -> String {
        let mut registry = Registry::with_prefix("citymesh");
        registry.register_collector(Box::new(m));
        let mut out = String::new();
        prometheus_client::encoding::text::encode(&mut out, &registry).unwrap();
        out
    }

    #[test]
    fn counts_by_route_and_status_and_buckets_latency() {
        let m = RequestMetrics::default();
        m.record("/tiles/{z}/{x}/{y}", 200, Duration::from_micros(300));
        m.record("/tiles/{z}/{x}/{y}", 200, Duration::from_millis(3));
        m.record("/tiles/{z}/{x}/{y}", 404, Duration::from_millis(40));
        m.record("unmatched", 404, Duration::from_secs(60));
        let text = rendered(m);
        for line in [
            "citymesh_http_requests_total{route=\"/tiles/{z}/{x}/{y}\",status=\"200\"} 2",
            "citymesh_http_requests_total{route=\"/tiles/{z}/{x}/{y}\",status=\"404\"} 1",
            "citymesh_http_requests_total{route=\"unmatched\",status=\"404\"} 1",
            "citymesh_http_request_duration_seconds_count{route=\"/tiles/{z}/{x}/{y}\"} 3",
            "citymesh_http_request_duration_seconds_sum{route=\"/tiles/{z}/{x}/{y}\"} 0.0433",
            "citymesh_http_request_duration_seconds_bucket{le=\"0.0005\",route=\"/tiles/{z}/{x}/{y}\"} 1",
            "citymesh_http_request_duration_seconds_bucket{le=\"0.005\",route=\"/tiles/{z}/{x}/{y}\"} 2",
            "citymesh_http_request_duration_seconds_bucket{le=\"0.05\",route=\"/tiles/{z}/{x}/{y}\"} 3",
            "citymesh_http_request_duration_seconds_bucket{le=\"30.0\",route=\"unmatched\"} 0",
            "citymesh_http_request_duration_seconds_bucket{le=\"+Inf\",route=\"unmatched\"} 1",
            "# TYPE citymesh_http_requests counter",
            "# TYPE citymesh_http_request_duration_seconds histogram",
        ] {
            assert!(text.lines().any(|l| l == line), "missing {line} in\n{text}");
        }
    }
}

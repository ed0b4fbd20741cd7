//! Prometheus metrics, served at `/metrics` in the text exposition format: requests by route and
//! status, request latency, cache hits and misses per level, upstream calls and errors, and
//! generation time.

mod requests;

use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::histogram::Histogram;
use prometheus_client::registry::Registry;
pub use requests::RequestMetrics;
use std::sync::Arc;

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RequestLabels {
    pub route: String,
    pub status: u16,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct RouteLabels {
    pub route: String,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct CacheLabels {
    /// `memory` (generated tiles in RAM), `sqlite` (generated tiles on disk), `osm_memory`
    /// (parsed OSM data tiles), `osm_sqlite` (stored OSM data tiles).
    pub level: &'static str,
    /// `hit` or `miss`.
    pub result: &'static str,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct UpstreamLabels {
    /// `ok`, `busy`, `timeout` or `bad_response`.
    pub result: &'static str,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct StateLabels {
    /// `queued`, `running`, `done`, `failed` or `cancelled`.
    pub state: String,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct SlotLabels {
    /// `general`, or `reserved` (`--reserved-connections`, only `/health` and `/metrics`).
    pub slot: &'static str,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
pub struct ResultLabels {
    /// `ok`, or why not (`not_found`, `busy`, `timeout`, `too_large`, `not_an_image`,
    /// `bad_response`).
    pub result: &'static str,
}

/// Every metric citymesh keeps.
pub struct Metrics {
    registry: Registry,
    /// Requests by route and status, latency by route.
    pub requests: Arc<RequestMetrics>,
    pub cache: Family<CacheLabels, Counter>,
    pub upstream: Family<UpstreamLabels, Counter>,
    pub generations: Counter,
    /// Generated tiles whose write to SQLite failed (served all the same).
    pub tile_store_failures: Counter,
    pub generation_seconds: Histogram,
    /// Roof jobs by state (set after each worker round and each new batch).
    pub roof_jobs: Family<StateLabels, prometheus_client::metrics::gauge::Gauge>,
    pub imagery_fetches: Family<ResultLabels, Counter>,
    /// Time to classify one batch of crops.
    pub inference_seconds: Histogram,
    /// Bytes each memory cache weighs (set when /metrics is read), and the budget.
    pub memory_cache_bytes: Family<CacheNameLabels, prometheus_client::metrics::gauge::Gauge>,
    /// What this replica did with others on one PostgreSQL.
    pub replicas: ReplicaMetrics,
    /// Client connections holding a slot now, by slot (a slot is free again once this falls).
    pub connections_open: Family<SlotLabels, prometheus_client::metrics::gauge::Gauge>,
    /// Following a replication feed.
    pub replication: ReplicationMetrics,
}

/// How fresh the data is, and what following a feed did (`serve --replicate-url`; the
/// sequence and age are read from the database, so they hold for `citymesh replicate` too).
#[derive(Default, Clone)]
pub struct ReplicationMetrics {
    /// Diffs this process applied.
    pub diffs_applied: Counter,
    /// Tries to follow the feed that failed (each retried after a back-off).
    pub errors: Counter,
    /// The sequence number of the last diff applied (0: none).
    pub sequence: prometheus_client::metrics::gauge::Gauge,
    /// Seconds from the applied data's timestamp to now: how far behind OpenStreetMap it is.
    pub lag_seconds: prometheus_client::metrics::gauge::Gauge,
}

impl ReplicationMetrics {
    fn register(&self, registry: &mut Registry) {
        registry.register(
            "replication_diffs_applied",
            "Replication diffs this process applied",
            self.diffs_applied.clone(),
        );
        registry.register(
            "replication_errors",
            "Tries to follow the replication feed that failed (retried after a back-off)",
            self.errors.clone(),
        );
        registry.register(
            "replication_sequence",
            "Sequence number of the last replication diff applied to the data (0: none)",
            self.sequence.clone(),
        );
        registry.register(
            "replication_lag_seconds",
            "Seconds from the timestamp of the data's last diff to now",
            self.lag_seconds.clone(),
        );
    }
}

/// Counters of the work replicas share (all zero on SQLite but `roof_jobs_*`).
#[derive(Default, Clone)]
pub struct ReplicaMetrics {
    /// Misses that found another replica generating the same tile and waited for it.
    pub generation_lock_waits: Counter,
    /// ... and whose wait ran out, so they generated it too.
    pub generation_lock_timeouts: Counter,
    /// Data changes announced by other replicas (or `citymesh import`) and acted on.
    pub data_change_notifications: Counter,
    /// Times the listener for those announcements (re)connected; each drops the memory caches.
    pub listener_connects: Counter,
    /// Roof jobs this replica's workers claimed.
    pub roof_jobs_claimed: Counter,
    /// Claimed jobs whose lease had run out before they were done (another claim took them).
    pub roof_jobs_lease_lost: Counter,
}

impl ReplicaMetrics {
    fn register(&self, registry: &mut Registry) {
        let counters = [
            (
                "generation_lock_waits",
                "Misses that waited for another replica generating the same tile",
                &self.generation_lock_waits,
            ),
            (
                "generation_lock_timeouts",
                "Misses whose wait for another replica ran out, so they generated the tile too",
                &self.generation_lock_timeouts,
            ),
            (
                "data_change_notifications",
                "Data changes announced by other replicas through PostgreSQL and acted on",
                &self.data_change_notifications,
            ),
            (
                "notification_listener_connects",
                "Connections of the data-change listener (each drops the memory caches)",
                &self.listener_connects,
            ),
            (
                "roof_jobs_claimed",
                "Roof jobs claimed by this replica's workers",
                &self.roof_jobs_claimed,
            ),
            (
                "roof_jobs_lease_lost",
                "Claimed roof jobs whose lease ran out before they were done",
                &self.roof_jobs_lease_lost,
            ),
        ];
        for (name, help, counter) in counters {
            registry.register(name, help, counter.clone());
        }
    }
}

#[derive(Debug, Clone, Hash, PartialEq, Eq, prometheus_client::encoding::EncodeLabelSet)]
pub struct CacheNameLabels {
    /// `tiles`, `scenes`, `dem`, `osm_tiles`, `building_sets`, or `budget` (the whole budget).
    pub cache: &'static str,
}

fn latency_buckets() -> impl Iterator<Item = f64> {
    [
        0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0,
    ]
    .into_iter()
}

impl Default for Metrics {
    fn default() -> Self {
        let mut registry = Registry::with_prefix("citymesh");
        let requests = Arc::new(RequestMetrics::default());
        let cache = Family::<CacheLabels, Counter>::default();
        let upstream = Family::<UpstreamLabels, Counter>::default();
        let generations = Counter::default();
        let tile_store_failures = Counter::default();
        let generation_seconds = Histogram::new(latency_buckets());
        let roof_jobs = Family::default();
        let imagery_fetches = Family::<ResultLabels, Counter>::default();
        let inference_seconds = Histogram::new(latency_buckets());
        let memory_cache_bytes = Family::default();
        let connections_open = Family::default();
        registry.register(
            "connections_open",
            "Client connections holding a slot now, by slot (general or reserved)",
            connections_open.clone(),
        );
        registry.register(
            "memory_cache_bytes",
            "Bytes each memory cache holds, weighed as it is bounded (cache=budget: --memory-mb)",
            memory_cache_bytes.clone(),
        );
        registry.register(
            "roof_jobs",
            "Roof classification jobs by state",
            roof_jobs.clone(),
        );
        registry.register(
            "imagery_fetches",
            "Imagery tile requests by result",
            imagery_fetches.clone(),
        );
        registry.register(
            "roof_inference_duration_seconds",
            "Time to classify one batch of roof crops",
            inference_seconds.clone(),
        );
        registry.register_collector(Box::new(requests.clone()));
        registry.register(
            "cache_requests",
            "Cache lookups by level (memory, sqlite or postgres, osm_memory, osm_sqlite or osm_postgres) and result",
            cache.clone(),
        );
        registry.register(
            "upstream_requests",
            "Overpass requests by result (ok, busy, timeout, bad_response)",
            upstream.clone(),
        );
        registry.register("generations", "Meshes generated", generations.clone());
        let replicas = ReplicaMetrics::default();
        replicas.register(&mut registry);
        let replication = ReplicationMetrics::default();
        replication.register(&mut registry);
        registry.register(
            "tile_store_write_failures",
            "Generated tiles not written to the database (served all the same)",
            tile_store_failures.clone(),
        );
        registry.register(
            "generation_duration_seconds",
            "Time to generate a mesh and its GLB",
            generation_seconds.clone(),
        );
        Self {
            registry,
            requests,
            cache,
            upstream,
            generations,
            tile_store_failures,
            generation_seconds,
            roof_jobs,
            imagery_fetches,
            inference_seconds,
            memory_cache_bytes,
            replicas,
            connections_open,
            replication,
        }
    }
}

impl Metrics {
    /// Counts a cache lookup.
    pub fn cache(&self, level: &'static str, hit: bool) {
        self.cache
            .get_or_create(&CacheLabels {
                level,
                result: if hit { "hit" } else { "miss" },
            })
            .inc();
    }

    /// Counts a miss's wait for another replica's generation.
    pub fn generation_lock_waits(&self, waited: bool, timed_out: bool) {
        if waited {
            self.replicas.generation_lock_waits.inc();
        }
        if timed_out {
            self.replicas.generation_lock_timeouts.inc();
        }
    }

    /// The text exposition format.
    pub fn render(&self) -> String {
        let mut out = String::new();
        if prometheus_client::encoding::text::encode(&mut out, &self.registry).is_err() {
            tracing::error!("metrics could not be encoded");
        }
        out
    }
}

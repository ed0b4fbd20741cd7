//! The generator a server or an export runs on, built from the options: the database, the DEM
//! store, the building source (imported data with Overpass, `--osm` files, or the demo city when
//! nothing is configured), the generation slots and limits, the roof predictions and priors.
//! `citymesh serve` puts caches and a listener around it (`super::build_state`); `citymesh
//! export` uses it alone.

use crate::cache::{MemoryBudget, PRIORS_KEPT, RoofPriors};
use crate::cli::ServeArgs;
use crate::clock::Clock;
use crate::db::Database;
use crate::dem::DemStore;
use crate::metrics::Metrics;
use crate::pipeline::{Generator, GeneratorParts};
use crate::roofs::classifier::RoofClassifier;
use crate::roofs::jobs::{JobQueue, RoofJobs};
use crate::source::data_tiles::{DataTileMemory, OsmTileStore};
use crate::source::{BuildingSource, DataTileSource, FileSource, load_osm_files};
use crate::state::Limits;
use crate::upstream::{OverpassClient, OverpassConfig};
use anyhow::Context;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::procedural::ProceduralParams;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Semaphore;

/// A generator and what else start-up learnt on the way.
pub struct OpenedGenerator {
    pub generator: Generator,
    pub database: Database,
    pub memory: MemoryBudget,
    /// The roof classifier, if one was asked for and loaded.
    pub classifier: Option<Arc<dyn RoofClassifier>>,
    /// Nothing was configured: the source is the procedural demo city.
    pub demo: bool,
    /// What generated content depends on (version, DEM, source, height base, roof method):
    /// stored tiles of another version are never served.
    pub data_version: String,
}

/// Opens the generator the options describe, its rows stamped by `clock`, announcing itself to
/// other replicas as `replica`.
pub async fn open_generator(
    args: &ServeArgs,
    clock: Clock,
    replica: &str,
) -> anyhow::Result<OpenedGenerator> {
    anyhow::ensure!(
        args.min_zoom <= args.max_zoom,
        "--min-zoom {} is above --max-zoom {}",
        args.min_zoom,
        args.max_zoom
    );
    anyhow::ensure!(
        args.max_zoom <= 30,
        "--max-zoom {} is above 30",
        args.max_zoom
    );
    anyhow::ensure!(args.max_bbox_km2 > 0.0, "--max-bbox-km2 must be positive");
    anyhow::ensure!(
        args.overpass_timeout_s > 0.0 && args.overpass_timeout_s.is_finite(),
        "--overpass-timeout-s must be a positive number of seconds"
    );
    for (flag, value) in [
        ("--request-timeout-s", args.request_timeout_s),
        ("--header-timeout-s", args.header_timeout_s),
        ("--body-timeout-s", args.body_timeout_s),
        ("--idle-timeout-s", args.idle_timeout_s),
        ("--first-byte-timeout-s", args.first_byte_timeout_s),
    ] {
        anyhow::ensure!(
            value > 0.0 && value.is_finite() && value < 1e9,
            "{flag} must be a positive number of seconds"
        );
    }
    anyhow::ensure!(
        args.idle_timeout_s > args.request_timeout_s,
        "--idle-timeout-s ({}) must be longer than --request-timeout-s ({}): a connection waiting \
         for its answer is silent meanwhile",
        args.idle_timeout_s,
        args.request_timeout_s
    );
    let overpass_urls = args
        .overpass_url
        .clone()
        .unwrap_or_else(|| vec![crate::upstream::DEFAULT_OVERPASS_URL.to_owned()]);
    anyhow::ensure!(
        !overpass_urls.is_empty(),
        "--overpass-url needs at least one endpoint"
    );
    anyhow::ensure!(
        args.world_area.is_none() || (!args.offline && args.osm.is_empty()),
        "--world-area is for a server that fetches from Overpass: with --offline or --osm there \
         is nothing to fetch, and the world tileset covers the data held without it"
    );
    let database = args.database.open().await?;
    // Cancelled on shutdown: long work (adaptations, tree measurements) stops.
    let stopping = tokio_util::sync::CancellationToken::new();
    let dem_dir = args.dem_dir.clone();
    let memory = MemoryBudget::of_megabytes(args.memory_mb);
    let dem = tokio::task::spawn_blocking(move || DemStore::open(&dem_dir, memory.dem)).await?;
    let metrics = Arc::new(Metrics::default());
    let store = OsmTileStore::bounded(database.clone(), args.osm_store_mb.saturating_mul(1 << 20))
        .with_clock(clock.clone());
    // Nothing configured at all: a procedural city, so a fresh `cargo run` shows something.
    let demo = args.osm.is_empty()
        && args.overpass_url.is_none()
        && !args.offline
        && args.world_area.is_none()
        && dem.file_count() == 0
        && store.count().await? == 0;
    let files = if demo {
        let city = tokio::task::spawn_blocking(move || {
            citymesh_core::procedural::generate_city(&ProceduralParams::default()).map(|city| {
                FileSource::new(BuildingSet::new(city.records), "demo")
                    .bound_priors(memory.roof_priors / PRIORS_KEPT)
            })
        })
        .await??;
        Some(city)
    } else if args.osm.is_empty() {
        None
    } else {
        let osm_files = args.osm.clone();
        let data = tokio::task::spawn_blocking(move || {
            load_osm_files(&osm_files).map(|f| f.bound_priors(memory.roof_priors / PRIORS_KEPT))
        })
        .await??;
        tracing::info!(
            buildings = data.set.records().len(),
            clusters = data.set.clusters().len(),
            skipped = data.load_skips.len(),
            repaired = data.repaired.len(),
            "OSM buildings indexed"
        );
        Some(data)
    };
    let source: Arc<dyn BuildingSource> = match files {
        Some(data) => Arc::new(data),
        None => {
            let upstream = if args.offline {
                None
            } else {
                Some(Arc::new(
                    OverpassClient::new(OverpassConfig {
                        urls: overpass_urls,
                        timeout: Duration::from_secs_f64(args.overpass_timeout_s),
                        retries: args.overpass_retries,
                        backoff: Duration::from_secs(1),
                        max_concurrent: args.overpass_max_concurrent,
                        max_bytes: args.overpass_max_mb.saturating_mul(1 << 20),
                        calls_per_minute: args.overpass_calls_per_minute,
                    })?
                    .with_clock(clock),
                ))
            };
            DataTileSource::new(
                store,
                upstream,
                (args.osm_ttl_hours * 3600.0) as i64,
                args.overpass_calls_per_request,
                DataTileMemory {
                    parsed_bytes: memory.osm_tiles,
                    set_bytes: memory.building_sets,
                },
                metrics.clone(),
            )
        }
    };
    let height_base = citymesh_core::building::HeightBase::from(args.height_base);
    let roof_method = citymesh_core::building::RoofMethod::from(args.roof_method);
    let data_version = format!(
        "{}-{}-{}-{}-{}",
        env!("CARGO_PKG_VERSION"),
        dem.fingerprint(),
        source.fingerprint(),
        height_base.name(),
        roof_method.name()
    );
    let slots = args
        .max_generations
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, std::num::NonZero::get))
        .max(1);
    let classifier = if args.roof_classifier {
        let c = &args.classifier;
        match crate::roofs::classifier::load_onnx(
            c.onnxruntime_lib.as_deref(),
            c.roof_model.as_deref(),
            c.roof_passes,
        ) {
            Ok(classifier) => {
                tracing::info!(model_id = classifier.model_id(), "roof classifier loaded");
                Some(classifier)
            }
            Err(e) => {
                tracing::warn!("roof classifier off: {e}");
                None
            }
        }
    } else {
        None
    };
    let model_id = match (&classifier, &args.classifier.roof_model) {
        (Some(c), _) => c.model_id().to_owned(),
        (None, Some(path)) => crate::roofs::classifier::model_id_of(
            &std::fs::read(path).with_context(|| format!("reading {}", path.display()))?,
        ),
        (None, None) => crate::roofs::classifier::model_id_of(crate::roofs::classifier::MODEL),
    };
    let imagery = args
        .imagery
        .open(&database, Some(metrics.clone()))
        .await?
        .map(Arc::new);
    let roofs = Arc::new(
        RoofJobs::new(
            JobQueue::new(&database),
            args.imagery.imagery_id.clone(),
            args.imagery.imagery_attribution.clone(),
            model_id,
            imagery,
            classifier.clone(),
            args.roof_threshold.clamp(0.0, 1.0),
            metrics.clone(),
            roof_jobs_config(args, replica, &stopping)?,
        )
        .await?,
    );
    tracing::info!(
        predictions = roofs.active().index.len(),
        imagery = %roofs.imagery_id,
        "roof predictions loaded"
    );
    let priors = Arc::new(RoofPriors::new(memory.roof_priors));
    let classifier = classifier.map(|c| c as Arc<dyn crate::roofs::classifier::RoofClassifier>);
    let generator = Generator::new(GeneratorParts {
        source,
        dem: Arc::new(dem),
        generations: Arc::new(Semaphore::new(slots)),
        limits: Limits {
            max_bbox_km2: args.max_bbox_km2,
            max_ground_cells: args.max_ground_cells,
            max_scene_nodes: args.max_scene_nodes,
            min_zoom: args.min_zoom,
            max_zoom: args.max_zoom,
            generation_wait: Duration::from_millis(args.generation_wait_ms),
            request_timeout: Duration::from_secs_f64(args.request_timeout_s),
            body_timeout: Duration::from_secs_f64(args.body_timeout_s),
        },
        metrics: metrics.clone(),
        height_base,
        roof_method,
        roofs,
        priors,
        stopping,
        world_area: args.world_area,
    });
    Ok(OpenedGenerator {
        generator,
        database,
        memory,
        classifier,
        demo,
        data_version,
    })
}

/// The bounds on classification batches and adaptations the options give.
fn roof_jobs_config(
    args: &ServeArgs,
    replica: &str,
    stopping: &tokio_util::sync::CancellationToken,
) -> anyhow::Result<crate::roofs::jobs::RoofJobsConfig> {
    use crate::roofs::jobs::adapt::{AdaptPolicy, Lease};
    use crate::roofs::jobs::batch_budget::BatchLimits;
    anyhow::ensure!(
        (0.0..=100.0).contains(&args.classify_client_share_percent),
        "--classify-client-share-percent must be 0 to 100"
    );
    for (flag, value) in [
        ("--classify-batch-ttl-s", args.classify_batch_ttl_s),
        ("--adapt-max-s", args.adapt_max_s),
    ] {
        anyhow::ensure!(
            value >= 0.0 && value.is_finite() && value < 1e9,
            "{flag} must be a number of seconds, 0 or more"
        );
    }
    let max_bytes = args.classify_store_mb.saturating_mul(1 << 20);
    Ok(crate::roofs::jobs::RoofJobsConfig {
        batch_limits: BatchLimits {
            max_bytes,
            client_bytes: (max_bytes as f64 * args.classify_client_share_percent / 100.0) as u64,
            ttl: Duration::from_secs_f64(args.classify_batch_ttl_s),
        },
        adapt: AdaptPolicy {
            accept_any: args.adapt_accept_any,
            max_run: Duration::from_secs_f64(args.adapt_max_s),
            lease: Lease {
                owner: replica.to_owned(),
                duration: Duration::from_secs_f64(args.classify_lease_s.clamp(1.0, 86_400.0)),
            },
        },
        stopping: stopping.clone(),
    })
}

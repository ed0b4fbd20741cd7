//! Options of `citymesh serve` (and of the data behind `export`).

use super::*;
use clap::Parser;
use std::net::SocketAddr;
use std::path::PathBuf;

/// Options of `citymesh serve`.
#[derive(Debug, Clone, Parser)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "CITYMESH_LISTEN", default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,

    /// Directory of SRTM files (.hgt, .hgt.gz, .hgt.zip; SRTM3 or SRTM1; searched recursively).
    /// Areas without a file get flat ground at 0 m.
    #[arg(long, env = "CITYMESH_DEM_DIR", default_value = "data/dem")]
    pub dem_dir: PathBuf,

    #[command(flatten)]
    pub database: super::DatabaseArgs,

    /// How long a tile this replica misses waits for another replica generating the same tile
    /// (PostgreSQL only) before generating it too, milliseconds.
    #[arg(
        long,
        env = "CITYMESH_GENERATION_LOCK_WAIT_MS",
        default_value_t = 10_000
    )]
    pub generation_lock_wait_ms: u64,

    /// OSM data to serve buildings from: OSM PBF, OSM XML or Overpass JSON, optionally gzipped.
    /// Repeat the flag (or separate files with commas in CITYMESH_OSM) for several files. Without
    /// it, buildings come from data tiles: the cache database, filled by `citymesh import` or
    /// from Overpass.
    #[arg(long = "osm", env = "CITYMESH_OSM", value_delimiter = ',')]
    pub osm: Vec<PathBuf>,

    /// Overpass API endpoint(s), tried in turn when one fails (repeat the flag, or separate with
    /// commas). Default: the public main instance, https://overpass-api.de/api/interpreter. With
    /// no data at all configured (no --osm, no --overpass-url, no --dem-dir files, nothing
    /// imported), citymesh serves a procedural demo city instead.
    #[arg(long, env = "CITYMESH_OVERPASS_URL", value_delimiter = ',')]
    pub overpass_url: Option<Vec<String>>,

    /// Origins (e.g. `https://app.example.org`; comma-separated in the variable) whose web pages
    /// may queue, cancel and adapt classification (`POST` and `DELETE` under `/classify`).
    /// Every origin may read; by default only the server's own pages may change state. Clients
    /// that send no `Origin` header (curl, scripts) are not affected.
    #[arg(long, env = "CITYMESH_CORS_ORIGIN", value_delimiter = ',')]
    pub cors_origin: Vec<String>,

    /// Largest GeoJSON document `POST /scene.glb` accepts, in megabytes.
    #[arg(long, env = "CITYMESH_MAX_UPLOAD_MB", default_value_t = 10)]
    pub max_upload_mb: u64,

    /// Most features a posted GeoJSON may have.
    #[arg(long, env = "CITYMESH_MAX_FEATURES", default_value_t = 20_000)]
    pub max_features: usize,

    /// Most positions (vertices) a posted GeoJSON may have over all its features.
    #[arg(long, env = "CITYMESH_MAX_VERTICES", default_value_t = 1_000_000)]
    pub max_vertices: usize,

    /// Never call Overpass: data tiles not in the cache database have no buildings.
    #[arg(long, env = "CITYMESH_OFFLINE")]
    pub offline: bool,

    /// The area the world tileset (`/3dtiles/tileset.json` without a box) covers on a server
    /// that fetches from Overpass, beyond the data it holds: `minLon,minLat,maxLon,maxLat`, or
    /// `world` for the whole Web Mercator square. Its leaves fetch their data tiles when a
    /// client first asks for them; coarse tiles draw blocks where data is held. Without it the
    /// tileset covers the data held (imported or fetched so far). Not with --offline or --osm
    /// (nothing to fetch).
    #[arg(long, env = "CITYMESH_WORLD_AREA", value_parser = world_area_arg)]
    pub world_area: Option<citymesh_core::geo::GeoBbox>,

    /// Load the roof-shape classifier at start-up (needs ONNX Runtime; without it citymesh says
    /// how to install it and serves everything else). Off: nothing is loaded.
    #[arg(long, env = "CITYMESH_ROOF_CLASSIFIER")]
    pub roof_classifier: bool,

    #[command(flatten)]
    pub classifier: ClassifierArgs,

    #[command(flatten)]
    pub imagery: ImageryArgs,

    /// Workers running queued roof jobs (with --roof-classifier and --imagery-url); 0: jobs are
    /// queued but only `citymesh classify` or another server runs them.
    #[arg(long, env = "CITYMESH_CLASSIFY_WORKERS", default_value_t = 1)]
    pub classify_workers: usize,

    /// Seconds a worker holds the jobs it claimed: a worker that dies (crash, kill -9) leaves
    /// them to be taken again after this.
    #[arg(long, env = "CITYMESH_CLASSIFY_LEASE_S", default_value_t = 120.0)]
    pub classify_lease_s: f64,

    /// Least top probability a prediction needs to give a roof its shape with `roofs=classified`.
    #[arg(long, env = "CITYMESH_ROOF_THRESHOLD", default_value_t = 0.6)]
    pub roof_threshold: f32,

    /// Megabytes the classification batches (a row and a link per building) may keep in the
    /// database; past it `POST /classify` answers 503 with Retry-After until batches expire or
    /// are deleted.
    #[arg(long, env = "CITYMESH_CLASSIFY_STORE_MB", default_value_t = 64)]
    pub classify_store_mb: u64,

    /// Share of --classify-store-mb one client (by IP address) may hold in live batches,
    /// percent; past it that client gets 429 with Retry-After.
    #[arg(
        long,
        env = "CITYMESH_CLASSIFY_CLIENT_SHARE_PERCENT",
        default_value_t = 25.0
    )]
    pub classify_client_share_percent: f64,

    /// Seconds a finished classification batch is kept after its last job ended; then
    /// `GET /classify/{id}` answers 404 (its predictions stay).
    #[arg(
        long,
        env = "CITYMESH_CLASSIFY_BATCH_TTL_S",
        default_value_t = 86_400.0
    )]
    pub classify_batch_ttl_s: f64,

    /// Put an adapted roof head in use even when its cross-validated accuracy does not beat the
    /// shipped head's on the same examples (by default such a head is stored as `not_better`).
    #[arg(long, env = "CITYMESH_ADAPT_ACCEPT_ANY")]
    pub adapt_accept_any: bool,

    /// Seconds an adaptation may run (cropping and fitting); past it it is stopped and failed.
    #[arg(long, env = "CITYMESH_ADAPT_MAX_S", default_value_t = 900.0)]
    pub adapt_max_s: f64,

    /// Seconds one Overpass request may take.
    #[arg(long, env = "CITYMESH_OVERPASS_TIMEOUT_S", default_value_t = 60.0)]
    pub overpass_timeout_s: f64,

    /// Retries of a failed Overpass request (429, 5xx, timeouts), with doubling backoff from
    /// 1 s, or the `Retry-After` Overpass sends.
    #[arg(long, env = "CITYMESH_OVERPASS_RETRIES", default_value_t = 2)]
    pub overpass_retries: u32,

    /// Overpass requests in flight at most (the public instance allows about two per client).
    #[arg(long, env = "CITYMESH_OVERPASS_MAX_CONCURRENT", default_value_t = 2)]
    pub overpass_max_concurrent: usize,

    /// OSM data tiles one request may fetch from Overpass; a request that needs more fetches
    /// that many, keeps them, and answers 503 (asking again goes further).
    #[arg(
        long,
        env = "CITYMESH_OVERPASS_CALLS_PER_REQUEST",
        default_value_t = 12
    )]
    pub overpass_calls_per_request: usize,

    /// Overpass calls (retries included) all requests together may start in any minute; past
    /// it, requests that need new data answer 503 with Retry-After.
    #[arg(long, env = "CITYMESH_OVERPASS_CALLS_PER_MINUTE", default_value_t = 60)]
    pub overpass_calls_per_minute: usize,

    /// Bound of the OSM data fetched from Overpass and stored in SQLite, megabytes; the least
    /// recently used data tiles are evicted past it (fetched again when needed). Imported data
    /// is never evicted.
    #[arg(long, env = "CITYMESH_OSM_STORE_MB", default_value_t = 1024)]
    pub osm_store_mb: u64,

    /// Follow this OpenStreetMap replication feed (`state.txt`, `AAA/BBB/CCC.osc.gz`) while
    /// serving: each diff is applied to the imported data, and what it changed is dropped from
    /// every cache (as `citymesh replicate` does, without a restart).
    #[arg(long, env = "CITYMESH_REPLICATE_URL")]
    pub replicate_url: Option<String>,

    /// The first sequence to apply when the store has applied none (see `citymesh replicate
    /// --from-sequence`).
    #[arg(
        long,
        env = "CITYMESH_REPLICATE_FROM_SEQUENCE",
        requires = "replicate_url"
    )]
    pub replicate_from_sequence: Option<i64>,

    /// Seconds between checks of the feed when caught up (errors back off from 1 s to 10 min).
    #[arg(long, env = "CITYMESH_REPLICATE_INTERVAL_S", default_value_t = 60,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub replicate_interval_s: u64,

    /// Hours after which stored Overpass data is refreshed (served meanwhile). Imported data is
    /// never refreshed (follow a feed with --replicate-url instead).
    #[arg(long, env = "CITYMESH_OSM_TTL_HOURS", default_value_t = 168.0)]
    pub osm_ttl_hours: f64,

    /// Memory for every cache, in megabytes: generated tiles and scenes 25 %, parsed DEM files
    /// 25 %, parsed OSM data tiles 20 %, building sets 30 % (each evicts the least recently
    /// used past its share). The process needs this plus its working memory per request.
    #[arg(long, env = "CITYMESH_MEMORY_MB", default_value_t = 1024)]
    pub memory_mb: u64,

    /// Generations running at once at most (default: the number of CPU cores).
    #[arg(long, env = "CITYMESH_MAX_GENERATIONS")]
    pub max_generations: Option<usize>,

    /// Milliseconds a request waits for a free generation slot before a 503 with Retry-After.
    #[arg(long, env = "CITYMESH_GENERATION_WAIT_MS", default_value_t = 10_000)]
    pub generation_wait_ms: u64,

    /// Seconds a request may spend gathering data and generating before a 503.
    #[arg(long, env = "CITYMESH_REQUEST_TIMEOUT_S", default_value_t = 120.0)]
    pub request_timeout_s: f64,

    /// Directory of the npm packages the pages use (three, 3d-tiles-renderer, cesium), as
    /// `npm ci` installs them; served under /vendor/.
    #[arg(long, env = "CITYMESH_ASSETS_DIR", default_value = "node_modules")]
    pub assets_dir: PathBuf,

    /// Log filter: error, warn, info, debug, trace, or a tracing directive like `citymesh=debug`.
    #[arg(long, env = "CITYMESH_LOG_LEVEL", default_value = "info")]
    pub log_level: String,

    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings) or `highest` (the paper's rule); `?height_base=` overrides it for a scene.
    #[arg(long, env = "CITYMESH_HEIGHT_BASE", value_enum, default_value_t = HeightBaseArg::Lowest)]
    pub height_base: HeightBaseArg,

    /// How hipped, gabled and pyramidal roofs are laid over footprints: `auto` (the straight
    /// skeleton for complex footprints, the virtual rectangle for near-rectangular ones),
    /// `rectangle` (the paper's, everywhere) or `skeleton` (everywhere).
    #[arg(long, env = "CITYMESH_ROOF_METHOD", value_enum, default_value_t = RoofMethodArg::Auto)]
    pub roof_method: RoofMethodArg,

    /// Largest bounding box /scene.glb accepts, in square kilometres.
    #[arg(long, env = "CITYMESH_MAX_BBOX_KM2", default_value_t = 25.0)]
    pub max_bbox_km2: f64,

    /// Most ground cells a requested box may span, counted at 1 arc-second (the finest SRTM
    /// grid): bounds long, thin boxes the area limit lets through.
    #[arg(long, env = "CITYMESH_MAX_GROUND_CELLS", default_value_t = 250_000)]
    pub max_ground_cells: u64,

    /// Most outline nodes (of every ring of the buildings drawn) one request may generate: a
    /// scene, tile or 3D Tiles content over more answers 400 `area_too_complex`. The working
    /// memory of a generation grows with them (about 1.4 KB per node at the peak), so this and
    /// the generation slots bound it: see docs/architecture.md, Limits. The default takes a
    /// 25 km2 box three times as dense as Kirchfeld (5,000 nodes per km2).
    #[arg(long, env = "CITYMESH_MAX_SCENE_NODES", default_value_t = 400_000)]
    pub max_scene_nodes: usize,

    /// Largest Overpass answer accepted, megabytes: a larger one is refused (502), nothing stored.
    #[arg(long, env = "CITYMESH_OVERPASS_MAX_MB", default_value_t = 64)]
    pub overpass_max_mb: u64,

    /// Bound of the SQLite store of generated tiles, megabytes; least recently used tiles are
    /// evicted past it (OSM data is never evicted by this).
    #[arg(long, env = "CITYMESH_TILE_STORE_MB", default_value_t = 2048)]
    pub tile_store_mb: u64,

    /// Most client connections open at once; further clients wait in the listen backlog.
    #[arg(long, env = "CITYMESH_MAX_CONNECTIONS", default_value_t = 1024)]
    pub max_connections: usize,

    /// Further connections kept for `/health` and `/metrics` when the others are all in use
    /// (any other path answers 503 on them).
    #[arg(long, env = "CITYMESH_RESERVED_CONNECTIONS", default_value_t = 8)]
    pub reserved_connections: usize,

    /// Seconds a new connection may stay silent before its first byte; then it is closed.
    #[arg(long, env = "CITYMESH_FIRST_BYTE_TIMEOUT_S", default_value_t = 5.0)]
    pub first_byte_timeout_s: f64,

    /// Seconds a client may take to send a request's headers.
    #[arg(long, env = "CITYMESH_HEADER_TIMEOUT_S", default_value_t = 10.0)]
    pub header_timeout_s: f64,

    /// Seconds a client may take to send a request's whole body, counted from its headers (a
    /// total deadline: a body trickled byte by byte is cut at it).
    #[arg(long, env = "CITYMESH_BODY_TIMEOUT_S", default_value_t = 30.0)]
    pub body_timeout_s: f64,

    /// Seconds a connection may stay without any traffic (between requests, or while a request
    /// is neither read nor answered) before it is closed.
    #[arg(long, env = "CITYMESH_IDLE_TIMEOUT_S", default_value_t = 150.0)]
    pub idle_timeout_s: f64,

    /// Lowest zoom level /tiles serves.
    #[arg(long, env = "CITYMESH_MIN_ZOOM", default_value_t = 12)]
    pub min_zoom: u8,

    /// Highest zoom level /tiles serves.
    #[arg(long, env = "CITYMESH_MAX_ZOOM", default_value_t = 20)]
    pub max_zoom: u8,
}

/// The value of `--world-area`: `world`, or a box.
fn world_area_arg(text: &str) -> Result<citymesh_core::geo::GeoBbox, String> {
    if text.trim().eq_ignore_ascii_case("world") {
        return Ok(citymesh_core::geo::GeoBbox::world());
    }
    text.parse::<citymesh_core::geo::GeoBbox>().map_err(|e| {
        format!("{e}; give minLon,minLat,maxLon,maxLat (e.g. 8.3,48.9,8.6,49.1) or `world`")
    })
}

//! The command line. Every flag can also be set with a `CITYMESH_*` environment variable.

use clap::{Parser, Subcommand};
use std::net::SocketAddr;
use std::path::PathBuf;

/// citymesh: 3D city meshes from OpenStreetMap and SRTM, on demand over HTTP.
#[derive(Debug, Parser)]
#[command(version, about)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the HTTP server (the default when no subcommand is given).
    Serve(Box<ServeArgs>),
    /// Print the OpenAPI description the server serves at /openapi.json.
    Openapi,
    /// Store OSM files (PBF, OSM XML or Overpass JSON, optionally .gz) as data tiles in the
    /// cache database, so `serve --offline` has buildings without any upstream.
    Import(ImportArgs),
    /// Make one scene from OSM and SRTM files into a GLB file (a batch export, no server):
    /// `citymesh scene --osm FILE --dem-dir DIR [--bbox ...] -o out.glb [--encoding meshopt]
    /// [--stats out.json]`.
    Scene(SceneArgs),
    /// Render a seeded set of synthetic roof crops (PNG) with labels, to train or test the roof
    /// classifier (training/roof_classifier/README.md).
    RenderRoofs(RenderRoofsArgs),
    /// Crop a labelled set of real roof images (a CSV of `file,label[,split,footprint_px_wkt]`)
    /// by citymesh's crop rule and write them as `render-roofs` writes renders, to train the
    /// roof classifier on real imagery (training/roof_classifier/README.md).
    CropLabelled(CropLabelledArgs),
    /// Fit a new head of the roof classifier on labelled crops of the user's imagery (a CSV of
    /// `file,label[,split,footprint_px_wkt]`), cross-validate it and write it for
    /// `classify-image --head`.
    AdaptRoofs(AdaptRoofsArgs),
    /// Classify the roof of one building per image (PNG or JPEG, any size, centred on the
    /// building): prints one JSON line per file with the class probabilities.
    ClassifyImage(ClassifyImageArgs),
    /// Write a static tree of tiles for a static file server or object store: a 3D Tiles
    /// tileset (`tileset.json`, `content/`, and `subtrees/` when implicit) or XYZ GLB tiles
    /// (`{z}/{x}/{y}.glb`),
    /// from the data the server would use (the serve options). Resumable: run the same command
    /// again after an interrupt and it writes only what is missing.
    Export(Box<ExportArgs>),
    /// Classify the roofs of OSM buildings from an XYZ imagery service, in the foreground: writes
    /// the predictions as GeoJSON and, with --all, how they agree with the roof:shape tags.
    Classify(ClassifyArgs),
}

/// Options of `citymesh classify`.
#[derive(Debug, Clone, Parser)]
pub struct ClassifyArgs {
    /// OSM files with the buildings (PBF, OSM XML or Overpass JSON, optionally .gz).
    #[arg(long, required = true)]
    pub osm: Vec<PathBuf>,

    /// Only buildings whose first node lies in this box: west,south,east,north.
    #[arg(long)]
    pub bbox: Option<String>,

    #[command(flatten)]
    pub imagery: ImageryArgs,

    /// SQLite file holding the jobs and predictions (the one `serve --cache-db` uses).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// Classify tagged buildings too and report the agreement with their roof:shape.
    #[arg(long)]
    pub all: bool,

    /// GeoJSON file to write the predictions to.
    #[arg(long, short)]
    pub out: PathBuf,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    #[command(flatten)]
    pub classifier: ClassifierArgs,
}

/// The imagery service roofs are classified from (configured by the operator only: requests
/// never name a URL).
#[derive(Debug, Clone, clap::Args)]
pub struct ImageryArgs {
    /// The imagery service's URL template: {z}, {x}, {y}, {-y} (TMS) or {q} (quadkey).
    #[arg(long, env = "CITYMESH_IMAGERY_URL")]
    pub imagery_url: Option<String>,

    /// Deepest zoom the imagery service has.
    #[arg(long, env = "CITYMESH_IMAGERY_MAX_ZOOM", default_value_t = 19)]
    pub imagery_max_zoom: u8,

    /// Imagery tile side in pixels.
    #[arg(long, default_value_t = 256)]
    pub imagery_tile_size: u32,

    /// Credit line of the imagery, reported with every prediction.
    #[arg(long, env = "CITYMESH_IMAGERY_ATTRIBUTION", default_value = "")]
    pub imagery_attribution: String,

    /// A short name for the imagery: predictions are kept per imagery and model.
    #[arg(long, env = "CITYMESH_IMAGERY_ID", default_value = "imagery")]
    pub imagery_id: String,

    /// Imagery requests in flight at most.
    #[arg(long, default_value_t = 4)]
    pub imagery_concurrency: usize,

    /// Hours a fetched imagery tile is kept in the cache database before it is fetched again.
    #[arg(long, env = "CITYMESH_IMAGERY_TTL_HOURS", default_value_t = 720.0)]
    pub imagery_ttl_hours: f64,

    /// Most megabytes of imagery tiles kept in the cache database (least recently used go first).
    #[arg(long, env = "CITYMESH_IMAGERY_CACHE_MB", default_value_t = 512)]
    pub imagery_cache_mb: u64,
}

impl ImageryArgs {
    /// The source these flags describe over the cache database `pool` (fetched tiles kept
    /// there), with `metrics`; `None` without `--imagery-url`.
    pub async fn open(
        &self,
        pool: &sqlx::SqlitePool,
        metrics: Option<std::sync::Arc<crate::metrics::Metrics>>,
    ) -> anyhow::Result<Option<crate::imagery::Imagery>> {
        let Some(spec) = self.spec() else {
            return Ok(None);
        };
        let ttl =
            std::time::Duration::from_secs_f64(self.imagery_ttl_hours.clamp(0.0, 1e6) * 3600.0);
        let cache = crate::imagery::ImageryCache::new(
            pool.clone(),
            ttl,
            self.imagery_cache_mb.saturating_mul(1 << 20),
        )
        .await?;
        let mut imagery = crate::imagery::Imagery::open(spec).await?.with_cache(cache);
        if let Some(m) = metrics {
            imagery = imagery.with_metrics(m);
        }
        Ok(Some(imagery))
    }

    /// The service these flags describe, `None` without `--imagery-url`.
    pub fn spec(&self) -> Option<crate::imagery::ImagerySpec> {
        let url = self.imagery_url.as_deref()?;
        let mut spec = crate::imagery::ImagerySpec::xyz(&self.imagery_id, url);
        spec.max_zoom = self.imagery_max_zoom;
        spec.tile_size = self.imagery_tile_size;
        spec.attribution.clone_from(&self.imagery_attribution);
        spec.max_concurrent = self.imagery_concurrency.max(1);
        Some(spec)
    }
}

/// Where the roof classifier's runtime and model come from.
#[derive(Debug, Clone, clap::Args)]
pub struct ClassifierArgs {
    /// ONNX Runtime's shared library (libonnxruntime.so >= 1.31, shipped by the PyPI
    /// `onnxruntime` wheel). Default: ORT_DYLIB_PATH, else ./.venv's wheel, else /usr/local/lib
    /// and /usr/lib.
    #[arg(long, env = "CITYMESH_ONNXRUNTIME_LIB")]
    pub onnxruntime_lib: Option<PathBuf>,

    /// An ONNX roof model to use instead of the built-in one (same input and output).
    #[arg(long, env = "CITYMESH_ROOF_MODEL")]
    pub roof_model: Option<PathBuf>,

    /// How many passes each crop is run in: `turns` (the turns and flips a crop allows; the
    /// model card's accuracy) or `shifted` (each of those also at 5 shifts: five times the
    /// cost).
    #[arg(long, env = "CITYMESH_ROOF_PASSES", value_enum, default_value_t)]
    pub roof_passes: crate::classifier::onnx::Passes,
}

/// Options of `citymesh classify-image`.
#[derive(Debug, Clone, Parser)]
pub struct ClassifyImageArgs {
    /// PNG or JPEG images, each a crop centred on one building.
    #[arg(required_unless_present = "labels")]
    pub files: Vec<PathBuf>,

    /// Classify the images of a labels file instead (`file,label` and optional `split` and
    /// `footprint_px_wkt` columns, images relative to it; the footprint is drawn as the mask):
    /// one line per image, then a summary line with the accuracy and confusion matrix.
    #[arg(long, conflicts_with = "footprint_mask")]
    pub labels: Option<PathBuf>,

    /// With --labels: only the rows of this split (e.g. `val`).
    #[arg(long, requires = "labels")]
    pub split: Option<String>,

    /// A head fitted by `citymesh adapt-roofs` to use instead of the shipped one.
    #[arg(long)]
    pub head: Option<PathBuf>,

    /// The image's alpha channel is the footprint (opaque inside): crop by the footprint's
    /// rotated rectangle exactly as citymesh crops imagery, and give the model the mask.
    #[arg(long)]
    pub footprint_mask: bool,

    #[command(flatten)]
    pub classifier: ClassifierArgs,
}

/// Options of `citymesh adapt-roofs`.
#[derive(Debug, Clone, Parser)]
pub struct AdaptRoofsArgs {
    /// Labelled crops: `file,label` and optional `split` and `footprint_px_wkt` columns (the
    /// Atlanta `labels.csv` layout), images relative to the CSV.
    #[arg(long, required_unless_present = "osm", conflicts_with = "osm")]
    pub labels: Option<PathBuf>,

    /// With --labels: only the rows of this split (e.g. `train`).
    #[arg(long, requires = "labels")]
    pub split: Option<String>,

    /// Or OSM files (PBF, OSM XML or Overpass JSON, optionally .gz): their buildings whose
    /// `roof:shape` is flat, gabled, hipped or pyramidal are the examples, cropped from
    /// --imagery-url as the server crops any building. The head is also stored in --cache-db for
    /// that imagery, where `serve` uses it.
    #[arg(long)]
    pub osm: Vec<PathBuf>,

    /// With --osm: only buildings whose footprint's centre lies in this box:
    /// west,south,east,north.
    #[arg(long, requires = "osm")]
    pub bbox: Option<String>,

    #[command(flatten)]
    pub imagery: ImageryArgs,

    /// With --osm: the SQLite file the head is stored in (the one `serve --cache-db` uses).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// The head file to write (JSON).
    #[arg(long, short)]
    pub out: PathBuf,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    #[command(flatten)]
    pub classifier: ClassifierArgs,
}

/// Options of `citymesh crop-labelled`.
#[derive(Debug, Clone, Parser)]
pub struct CropLabelledArgs {
    /// The labels file: `file,label` and optional `split` and `footprint_px_wkt` columns,
    /// images relative to it.
    #[arg(long)]
    pub labels: PathBuf,

    /// Only the rows of this split (e.g. `train`).
    #[arg(long)]
    pub split: Option<String>,

    /// Directory to write `images/*.png` and `labels.csv` into.
    #[arg(long, short)]
    pub out: PathBuf,
}

/// Options of `citymesh render-roofs`.
#[derive(Debug, Clone, Parser)]
pub struct RenderRoofsArgs {
    /// OSM files whose real footprints are drawn (with randomly assigned roof shapes).
    #[arg(long)]
    pub osm: Vec<PathBuf>,

    /// Seeds of procedural cities whose footprints are drawn as well.
    #[arg(long, value_delimiter = ',')]
    pub procedural: Vec<u64>,

    /// Number of samples (classes cycle flat, gabled, hipped).
    #[arg(long, default_value_t = 1000)]
    pub count: u64,

    /// Seed of the whole set.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,

    /// Colours to draw from: `training` or `holdout` (the test set's).
    #[arg(long, default_value = "training")]
    pub palette: String,

    /// Directory to write `images/*.png` and `labels.csv` into.
    #[arg(long, short)]
    pub out: PathBuf,
}

/// Options of `citymesh scene`.
#[derive(Debug, Clone, Parser)]
pub struct SceneArgs {
    /// OSM data: OSM PBF, OSM XML or Overpass JSON, optionally gzipped (repeat for several).
    #[arg(long, required = true)]
    pub osm: Vec<PathBuf>,

    /// Directory with SRTM .hgt files (searched recursively); missing ones leave the ground flat
    /// at 0 m there, with a warning.
    #[arg(long, default_value = "data/dem")]
    pub dem_dir: PathBuf,

    /// The area as minLon,minLat,maxLon,maxLat: buildings are cut at its border, as `/scene`
    /// does. Default: every building whole, on the ground of their extent.
    #[arg(long)]
    pub bbox: Option<String>,

    /// The GLB file to write.
    #[arg(long, short)]
    pub out: PathBuf,

    /// How the GLB stores vertices: plain, quantized or meshopt.
    #[arg(long, value_enum, default_value_t = EncodingArg::Plain)]
    pub encoding: EncodingArg,

    /// Also write the scene's figures (buildings, roofs, ground, bytes, timings) as JSON here.
    #[arg(long)]
    pub stats: Option<PathBuf>,

    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings) or `highest` (the paper's rule).
    #[arg(long, value_enum, default_value_t = HeightBaseArg::Lowest)]
    pub height_base: HeightBaseArg,

    /// How hipped, gabled and pyramidal roofs are laid over footprints: `auto` (the straight
    /// skeleton for complex footprints, the virtual rectangle for near-rectangular ones),
    /// `rectangle` (the paper's, everywhere) or `skeleton` (everywhere).
    #[arg(long, value_enum, default_value_t = RoofMethodArg::Auto)]
    pub roof_method: RoofMethodArg,
}

/// `--roof-method`: how pitched roofs are laid over footprints (docs/method.md section 6b).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum RoofMethodArg {
    /// The straight skeleton for footprints with courtyards or filling less than 90 % of their
    /// virtual rectangle; the virtual rectangle for the others.
    #[default]
    Auto,
    /// The paper's virtual rectangle for every roof.
    Rectangle,
    /// The straight skeleton for every hipped, gabled and pyramidal roof.
    Skeleton,
}

impl From<RoofMethodArg> for citymesh_core::building::RoofMethod {
    fn from(m: RoofMethodArg) -> Self {
        match m {
            RoofMethodArg::Auto => Self::Auto,
            RoofMethodArg::Rectangle => Self::Rectangle,
            RoofMethodArg::Skeleton => Self::Skeleton,
        }
    }
}

/// `--height-base`: the ground a building's `height` is counted from (docs/method.md section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum HeightBaseArg {
    /// The lowest ground along the outline, as OpenStreetMap's Simple 3D Buildings defines.
    #[default]
    Lowest,
    /// The highest ground along the outline (the paper's Figure 5): taller on slopes.
    Highest,
}

impl From<HeightBaseArg> for citymesh_core::building::HeightBase {
    fn from(h: HeightBaseArg) -> Self {
        match h {
            HeightBaseArg::Lowest => Self::LowestGround,
            HeightBaseArg::Highest => Self::HighestGround,
        }
    }
}

/// `--encoding` of `citymesh scene`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum EncodingArg {
    Plain,
    Quantized,
    Meshopt,
}

impl From<EncodingArg> for citymesh_core::mesh::Encoding {
    fn from(e: EncodingArg) -> Self {
        match e {
            EncodingArg::Plain => Self::Plain,
            EncodingArg::Quantized => Self::Quantized,
            EncodingArg::Meshopt => Self::Meshopt,
        }
    }
}

/// Options of `citymesh export`.
#[derive(Debug, Clone, Parser)]
pub struct ExportArgs {
    /// The area as minLon,minLat,maxLon,maxLat (the 3D Tiles region; the XYZ tiles covering it).
    #[arg(long)]
    pub bbox: String,

    /// Where to write the tree: a directory (created if missing) or `file://` URL, or an
    /// S3-compatible object store as `s3://BUCKET/PREFIX` (credentials, region and endpoint from
    /// the usual `AWS_*` variables: `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, `AWS_REGION`,
    /// `AWS_ENDPOINT_URL` for a store other than Amazon's, `AWS_ALLOW_HTTP=true` for plain
    /// HTTP). Files already there are kept: a rerun resumes.
    #[arg(long, short)]
    pub out: String,

    /// `3dtiles` (as `/3dtiles/tileset.json` serves it) or `xyz`.
    #[arg(long, value_enum, default_value_t = ExportFormat::Tiles3d)]
    pub format: ExportFormat,

    /// How a 3D Tiles tileset lists its tiles: `explicit` (every tile written out) or
    /// `implicit` (a quadtree and its binary subtree), as `?tiling=` serves them.
    #[arg(long, value_enum, default_value_t = TilingArg::Explicit)]
    pub tiling: TilingArg,

    /// XYZ zoom levels, `A-B` or `A` (default 16).
    #[arg(long)]
    pub zooms: Option<String>,

    /// How GLBs store vertices (default: meshopt for 3D Tiles, plain for XYZ, as served).
    #[arg(long, value_enum)]
    pub encoding: Option<EncodingArg>,

    /// Tiles generated at once (default: the machine's cores).
    #[arg(long)]
    pub workers: Option<usize>,

    /// No progress bar or summary.
    #[arg(long)]
    pub quiet: bool,

    /// Where the data comes from, as for `serve` (--osm, --dem-dir, --cache-db, Overpass...).
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// `--format` of `citymesh export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// 3D Tiles 1.1.
    #[value(name = "3dtiles")]
    Tiles3d,
    /// XYZ GLB tiles.
    Xyz,
}

/// `--tiling` of `citymesh export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TilingArg {
    Explicit,
    Implicit,
}

impl From<TilingArg> for citymesh_core::tiles3d::Tiling {
    fn from(t: TilingArg) -> Self {
        match t {
            TilingArg::Explicit => Self::Explicit,
            TilingArg::Implicit => Self::Implicit,
        }
    }
}

/// Options of `citymesh import`.
#[derive(Debug, Clone, Parser)]
pub struct ImportArgs {
    /// The OSM files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,

    /// SQLite file to write into (the one `serve --cache-db` uses).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

impl Default for Command {
    fn default() -> Self {
        // No subcommand: serve with flags from the environment and the defaults.
        Command::Serve(Box::new(ServeArgs::parse_from(["serve"])))
    }
}

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

    /// SQLite file for cached data and generated tiles (created if missing; `:memory:` for none).
    #[arg(
        long,
        env = "CITYMESH_CACHE_DB",
        default_value = "data/citymesh.sqlite"
    )]
    pub cache_db: String,

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

    /// Hours after which stored Overpass data is refreshed (served meanwhile). Imported data is
    /// never refreshed.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serve_is_the_default_with_documented_defaults() {
        let Command::Serve(args) = Cli::parse_from(["citymesh"]).command.unwrap_or_default() else {
            panic!("no subcommand must mean serve");
        };
        assert_eq!(args.listen, "127.0.0.1:8080".parse().unwrap());
        assert_eq!(args.cache_db, "data/citymesh.sqlite");
        assert_eq!((args.min_zoom, args.max_zoom), (12, 20));
    }

    #[test]
    fn flags_parse() {
        let cli = Cli::parse_from([
            "citymesh",
            "serve",
            "--listen",
            "0.0.0.0:9000",
            "--dem-dir",
            "/x",
        ]);
        let Some(Command::Serve(args)) = cli.command else {
            panic!()
        };
        assert_eq!(args.listen.port(), 9000);
        assert_eq!(args.dem_dir, PathBuf::from("/x"));
    }
}

//! Options of the roof classifier's commands: `classify`, `classify-image`, `adapt-roofs`,
//! `crop-labelled`, `render-roofs`, and the imagery and model options they share with `serve`.

use clap::Parser;
use std::path::PathBuf;

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
    /// The source these flags describe over the database `db` (fetched tiles kept there), with
    /// `metrics`; `None` without `--imagery-url`.
    pub async fn open(
        &self,
        db: &crate::db::Database,
        metrics: Option<std::sync::Arc<crate::metrics::Metrics>>,
    ) -> anyhow::Result<Option<crate::roofs::imagery::Imagery>> {
        let Some(spec) = self.spec() else {
            return Ok(None);
        };
        let ttl =
            std::time::Duration::from_secs_f64(self.imagery_ttl_hours.clamp(0.0, 1e6) * 3600.0);
        let cache = crate::roofs::imagery::ImageryCache::new(
            db.clone(),
            ttl,
            self.imagery_cache_mb.saturating_mul(1 << 20),
        )
        .await?;
        let mut imagery = crate::roofs::imagery::Imagery::open(spec)
            .await?
            .with_cache(cache);
        if let Some(m) = metrics {
            imagery = imagery.with_metrics(m);
        }
        Ok(Some(imagery))
    }

    /// The service these flags describe, `None` without `--imagery-url`.
    pub fn spec(&self) -> Option<crate::roofs::imagery::ImagerySpec> {
        let url = self.imagery_url.as_deref()?;
        let mut spec = crate::roofs::imagery::ImagerySpec::xyz(&self.imagery_id, url);
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
    pub roof_passes: crate::roofs::classifier::onnx::Passes,
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

//! Imagery for the roof classifier, configured by the operator only (never named by a request, so
//! a client cannot make citymesh fetch from anywhere): XYZ and WMS services over HTTP ([`http`]:
//! polite fetching), local MBTiles files ([`mbtiles`]) and GeoTIFFs read chunk by chunk
//! ([`geotiff`]), fetched tiles kept in the cache database
//! ([`cache`]), all behind one [`Imagery`] ([`source`]) that accepts only whole images of the
//! expected size; [`crops`] cuts a building's crop from them by the model's crop rule.

mod cache;
mod crops;
mod geotiff;
mod http;
mod mbtiles;
mod source;

pub use cache::ImageryCache;
pub use crops::{CropFailure, MAX_TILES_PER_BUILDING, TileMemo, crop_footprint, prefetch_tiles};
pub use geotiff::{Crs, GeoTiff, MAX_CHUNKS_PER_TILE};
pub use http::{HttpImagery, UrlKind, WmsCrs, quadkey};
pub use source::Imagery;

/// One imagery service.
#[derive(Debug, Clone)]
pub struct ImagerySpec {
    /// A short name for results and logs.
    pub id: String,
    /// URL template with `{z}`, `{x}`, `{y}` (or `{-y}`, the TMS row from the south), or `{q}`
    /// (a Bing-style quadkey); a WMS GetMap template with `{bbox}` (or `{bbox_yx}`, latitude
    /// first, for WMS 1.3.0 in EPSG:4326), `{width}` and `{height}`; or a `.mbtiles`, `.tif` or
    /// `.tiff` file.
    pub url: String,
    /// Deepest zoom the service has.
    pub max_zoom: u8,
    /// Tile side in pixels.
    pub tile_size: u32,
    /// Whom to credit; reported with every result.
    pub attribution: String,
    /// Requests in flight at most.
    pub max_concurrent: usize,
    /// Retries after the first attempt.
    pub retries: u32,
    /// Seconds one request may take.
    pub timeout_s: f64,
    /// Largest tile accepted, bytes.
    pub max_bytes: u64,
}

impl ImagerySpec {
    /// A spec with polite defaults for a URL template.
    pub fn xyz(id: &str, url: &str) -> Self {
        Self {
            id: id.to_owned(),
            url: url.to_owned(),
            max_zoom: 19,
            tile_size: 256,
            attribution: String::new(),
            max_concurrent: 4,
            retries: 2,
            timeout_s: 15.0,
            max_bytes: 4 << 20,
        }
    }
}

/// Why a tile could not be had.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ImageryError {
    #[error("the imagery service has no tile here (HTTP 404)")]
    NotFound,
    #[error("the imagery service is rate limiting or overloaded (HTTP {0})")]
    Busy(u16),
    #[error("the imagery service did not answer within {0} s")]
    Timeout(f64),
    #[error("the imagery tile is larger than {0} bytes")]
    TooLarge(u64),
    #[error("the imagery tile is not a {expected}x{expected} PNG or JPEG: {detail}")]
    NotAnImage { expected: u32, detail: String },
    #[error("the imagery service failed: {0}")]
    Bad(String),
}

impl ImageryError {
    /// Whether asking again later may succeed (rate limits, timeouts, server errors).
    pub fn may_pass(&self) -> bool {
        matches!(self, ImageryError::Busy(_) | ImageryError::Timeout(_))
            || matches!(self, ImageryError::Bad(m) if m.starts_with("HTTP 5"))
    }

    /// A stable short name for reasons and metrics.
    pub fn kind(&self) -> &'static str {
        match self {
            ImageryError::NotFound => "not_found",
            ImageryError::Busy(_) => "busy",
            ImageryError::Timeout(_) => "timeout",
            ImageryError::TooLarge(_) => "too_large",
            ImageryError::NotAnImage { .. } => "not_an_image",
            ImageryError::Bad(_) => "bad_response",
        }
    }
}

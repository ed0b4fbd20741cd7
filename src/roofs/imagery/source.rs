//! One configured imagery source, whatever serves it: a service over HTTP (XYZ or WMS) or a local
//! MBTiles file, with fetched tiles kept in the cache database. Tiles come out decoded, checked
//! (a whole PNG or JPEG of exactly the tile size) and in Web Mercator rows.

use super::cache::ImageryCache;
use super::geotiff::GeoTiff;
use super::http::{HttpImagery, UrlKind, WmsCrs};
use super::mbtiles::MbTiles;
use super::{ImageryError, ImagerySpec};
use crate::metrics::{Metrics, ResultLabels};
use citymesh_core::geo::{TileCoord, mercator_y};
use citymesh_core::roof_image::Image;
use citymesh_core::roof_image::png_metadata::{MAX_PNG_TEXT_BYTES, png_text_bytes};
use std::sync::Arc;

enum Backend {
    Http(HttpImagery),
    MbTiles(MbTiles),
    GeoTiff(Arc<GeoTiff>),
}

pub struct Imagery {
    spec: ImagerySpec,
    backend: Backend,
    cache: Option<ImageryCache>,
    metrics: Option<Arc<Metrics>>,
}

impl Imagery {
    /// The source `spec.url` names: a path ending in `.mbtiles` (or `mbtiles:PATH`), `.tif` or
    /// `.tiff` is a local file, anything else an HTTP template (WMS when it has `{bbox}`).
    pub async fn open(spec: ImagerySpec) -> anyhow::Result<Self> {
        let local = spec
            .url
            .strip_prefix("mbtiles:")
            .or_else(|| spec.url.ends_with(".mbtiles").then_some(spec.url.as_str()))
            .map(std::path::PathBuf::from);
        let lower = spec.url.to_ascii_lowercase();
        let tiff = [".tif", ".tiff"]
            .iter()
            .any(|e| lower.ends_with(e))
            .then(|| std::path::PathBuf::from(&spec.url));
        let mut spec = spec;
        let backend = if let Some(path) = tiff {
            let size = spec.tile_size;
            let (file, native) =
                tokio::task::spawn_blocking(move || GeoTiff::open(&path, size)).await??;
            spec.max_zoom = spec.max_zoom.min(native);
            Backend::GeoTiff(file)
        } else if let Some(path) = local {
            let (file, max) = MbTiles::open(&path).await?;
            if let Some(max) = max {
                spec.max_zoom = spec.max_zoom.min(max);
            }
            Backend::MbTiles(file)
        } else {
            anyhow::ensure!(
                spec.url.starts_with("http://") || spec.url.starts_with("https://"),
                "--imagery-url '{}' is neither an http(s) URL template nor an .mbtiles file",
                spec.url
            );
            Backend::Http(HttpImagery::new(spec.clone())?)
        };
        Ok(Self {
            spec,
            backend,
            cache: None,
            metrics: None,
        })
    }

    /// Keeps fetched tiles in `cache` (local files are not cached).
    pub fn with_cache(self, cache: ImageryCache) -> Self {
        match self.backend {
            Backend::Http(_) => Self {
                cache: Some(cache),
                ..self
            },
            Backend::MbTiles(_) | Backend::GeoTiff(_) => self,
        }
    }

    /// Counts every tile's result in `metrics`.
    pub fn with_metrics(self, metrics: Arc<Metrics>) -> Self {
        Self {
            metrics: Some(metrics),
            ..self
        }
    }

    pub fn spec(&self) -> &ImagerySpec {
        &self.spec
    }

    /// The tile as an image in linear light, `tile_size` square, in Web Mercator rows.
    pub async fn tile(&self, t: TileCoord) -> Result<Image, ImageryError> {
        let result = self.tile_uncounted(t).await;
        if let Some(m) = &self.metrics {
            let result = match &result {
                Ok(_) => "ok",
                Err(e) => e.kind(),
            };
            m.imagery_fetches
                .get_or_create(&ResultLabels { result })
                .inc();
        }
        result
    }

    async fn tile_uncounted(&self, t: TileCoord) -> Result<Image, ImageryError> {
        let size = self.spec.tile_size;
        let id = &self.spec.id;
        if let Some(cache) = &self.cache {
            match cache.get(id, t).await {
                Ok(Some(bytes)) => {
                    if let Ok(image) = self.decode(&bytes, t) {
                        return Ok(image);
                    }
                }
                Ok(None) => {}
                Err(e) => tracing::warn!(error = %e, "imagery cache unreadable"),
            }
        }
        let bytes = match &self.backend {
            Backend::Http(http) => http.bytes(t).await?,
            Backend::MbTiles(file) => file.bytes(t).await?,
            Backend::GeoTiff(file) => {
                let file = file.clone();
                return tokio::task::spawn_blocking(move || file.tile(t))
                    .await
                    .map_err(|e| ImageryError::Bad(format!("GeoTIFF task: {e}")))?;
            }
        };
        let image = self.decode(&bytes, t)?;
        if let Some(cache) = &self.cache
            && let Err(e) = cache.put(id, t, &bytes).await
        {
            tracing::warn!(error = %e, size, "imagery tile not cached");
        }
        Ok(image)
    }

    /// Decodes and checks a tile, resampling degree rows (WMS in EPSG:4326) to Mercator rows.
    fn decode(&self, bytes: &[u8], t: TileCoord) -> Result<Image, ImageryError> {
        let image = decode(bytes, self.spec.tile_size)?;
        Ok(match &self.backend {
            Backend::Http(h) if h.kind() == UrlKind::Wms(WmsCrs::Wgs84) => {
                degree_rows_to_mercator(&image, t)
            }
            _ => image,
        })
    }
}

/// Decodes PNG or JPEG bytes of exactly `size` x `size` pixels.
pub fn decode(bytes: &[u8], size: u32) -> Result<Image, ImageryError> {
    let bad = |detail: String| ImageryError::NotAnImage {
        expected: size,
        detail,
    };
    let text = png_text_bytes(bytes);
    if text > MAX_PNG_TEXT_BYTES {
        return Err(bad(format!(
            "a PNG with {text} bytes of text metadata (more than {MAX_PNG_TEXT_BYTES})"
        )));
    }
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| bad(e.to_string()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(size);
    limits.max_image_height = Some(size);
    limits.max_alloc = Some(64 << 20);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| bad(e.to_string()))?;
    if decoded.width() != size || decoded.height() != size {
        return Err(bad(format!("{}x{}", decoded.width(), decoded.height())));
    }
    let rgb: Vec<[u8; 3]> = decoded.into_rgb8().pixels().map(|p| p.0).collect();
    Image::from_srgb8(size as usize, size as usize, &rgb).ok_or_else(|| bad("pixel count".into()))
}

/// An image whose rows are even steps of latitude over the tile, as rows even in Mercator y.
fn degree_rows_to_mercator(image: &Image, t: TileCoord) -> Image {
    let b = t.bounds();
    let (north, south) = (b.max_lat(), b.min_lat());
    let (y_top, y_bottom) = (mercator_y(north), mercator_y(south));
    let h = image.height;
    let mut out = image.clone();
    for row in 0..h {
        // The latitude at this Mercator row's centre (y in world units, 0 at the north edge),
        // and the row of even degrees holding it.
        let y = y_top + (y_bottom - y_top) * (row as f64 + 0.5) / h as f64;
        let lat = (std::f64::consts::PI * (1.0 - 2.0 * y))
            .sinh()
            .atan()
            .to_degrees();
        let source = degree_row(north, south, h, lat);
        let (from, to) = (source * image.width, row * image.width);
        out.pixels[to..to + image.width].copy_from_slice(&image.pixels[from..from + image.width]);
    }
    out
}

/// The row of an image spanning `north` to `south` in even degree steps that holds `lat`.
fn degree_row(north: f64, south: f64, height: usize, lat: f64) -> usize {
    ((north - lat) / (north - south) * height as f64 - 0.5)
        .round()
        .clamp(0.0, (height - 1) as f64) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 x 4 PNG, and the same with a zTXt chunk of `text` bytes (zeros deflated: it would
    /// inflate to about a thousand times that) inserted after its header.
    fn pngs(text: usize) -> (Vec<u8>, Vec<u8>) {
        let mut plain = Vec::new();
        image::RgbImage::from_pixel(4, 4, image::Rgb([200, 100, 50]))
            .write_to(
                &mut std::io::Cursor::new(&mut plain),
                image::ImageFormat::Png,
            )
            .unwrap();
        let mut data = b"Comment\0\0".to_vec();
        let mut zeros = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        while zeros.get_ref().len() < text {
            std::io::Write::write_all(&mut zeros, &[0u8; 1 << 20]).unwrap();
        }
        data.extend(zeros.finish().unwrap());
        let mut chunk = (data.len() as u32).to_be_bytes().to_vec();
        let mut crc = flate2::Crc::new();
        crc.update(b"zTXt");
        crc.update(&data);
        chunk.extend_from_slice(b"zTXt");
        chunk.extend_from_slice(&data);
        chunk.extend_from_slice(&crc.sum().to_be_bytes());
        // Signature (8) and IHDR (25) first.
        let mut with_text = plain[..33].to_vec();
        with_text.extend(chunk);
        with_text.extend_from_slice(&plain[33..]);
        (plain, with_text)
    }

    #[test]
    fn a_png_with_more_than_a_little_text_metadata_is_refused_before_decoding() {
        let (plain, small) = pngs(100);
        assert!(decode(&plain, 4).is_ok());
        assert!(decode(&small, 4).is_ok());
        let (_, bomb) = pngs(MAX_PNG_TEXT_BYTES + 1);
        let e = decode(&bomb, 4).unwrap_err().to_string();
        assert!(e.contains("text metadata"), "{e}");
    }

    #[test]
    fn degree_rows_move_north_in_mercator() {
        // A z2 tile spans 0 to 66.5 degrees north: Mercator stretches the north, so the middle
        // Mercator row shows a latitude above the middle degree row (40.98 degrees, not 33.3).
        let t = TileCoord::new(2, 2, 1).unwrap();
        let mut image = Image::filled(1, 256, [0.0; 3]);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            *p = [i as f32, 0.0, 0.0];
        }
        let out = degree_rows_to_mercator(&image, t);
        let b = t.bounds();
        let mid_lat = (std::f64::consts::PI * (1.0 - 2.0 * 0.375))
            .sinh()
            .atan()
            .to_degrees();
        assert!((mid_lat - 40.979_898).abs() < 1e-5);
        let want = degree_row(b.max_lat(), b.min_lat(), 256, mid_lat);
        // Row 128's centre is a hair below the middle: within one row of the middle latitude.
        let got = out.pixels[128][0] as usize;
        assert!(got.abs_diff(want) <= 1, "{got} vs {want}");
        assert!(got < 128);
        // Top and bottom rows stay at the edges.
        assert_eq!(out.pixels[0][0], 0.0);
        assert_eq!(out.pixels[255][0], 255.0);
    }
}

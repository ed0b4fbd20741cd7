//! An XYZ tile service: `{z}/{x}/{y}`, `{-y}` (TMS) or `{q}` (quadkey) URL templates.

use super::{ImageryError, ImagerySpec};
use citymesh_core::geo::TileCoord;
use citymesh_core::roof_image::Image;
use std::time::Duration;
use tokio::sync::Semaphore;

/// Longest wait between retries.
const MAX_BACKOFF: Duration = Duration::from_secs(10);

pub struct XyzImagery {
    spec: ImagerySpec,
    http: reqwest::Client,
    permits: Semaphore,
    metrics: Option<std::sync::Arc<crate::metrics::Metrics>>,
}

/// The Bing-style quadkey of a tile: one digit per zoom level.
pub fn quadkey(t: TileCoord) -> String {
    (1..=t.z)
        .rev()
        .map(|i| {
            let mask = 1u32 << (i - 1);
            let digit = u8::from(t.x & mask != 0) + 2 * u8::from(t.y & mask != 0);
            char::from(b'0' + digit)
        })
        .collect()
}

impl XyzImagery {
    pub fn new(spec: ImagerySpec) -> anyhow::Result<Self> {
        let timeout = Duration::from_secs_f64(spec.timeout_s.max(0.1));
        let http = reqwest::Client::builder()
            .user_agent(concat!(
                "citymesh/",
                env!("CARGO_PKG_VERSION"),
                " (roof classification; +https://github.com/citymesh)"
            ))
            .timeout(timeout)
            .connect_timeout(timeout.min(Duration::from_secs(10)))
            .build()?;
        Ok(Self {
            permits: Semaphore::new(spec.max_concurrent.max(1)),
            spec,
            http,
            metrics: None,
        })
    }

    /// Counts every tile request's result in `metrics`.
    pub fn with_metrics(self, metrics: std::sync::Arc<crate::metrics::Metrics>) -> Self {
        Self {
            metrics: Some(metrics),
            ..self
        }
    }

    pub fn spec(&self) -> &ImagerySpec {
        &self.spec
    }

    /// The tile's URL from the template.
    pub fn url(&self, t: TileCoord) -> String {
        let tms = (1u64 << t.z) - 1 - u64::from(t.y);
        self.spec
            .url
            .replace("{z}", &t.z.to_string())
            .replace("{x}", &t.x.to_string())
            .replace("{-y}", &tms.to_string())
            .replace("{y}", &t.y.to_string())
            .replace("{q}", &quadkey(t))
    }

    /// The tile as an image in linear light, `tile_size` square.
    pub async fn tile(&self, t: TileCoord) -> Result<Image, ImageryError> {
        let result = self.fetch(t).await;
        if let Some(m) = &self.metrics {
            let label = match &result {
                Ok(_) => "ok",
                Err(e) => e.kind(),
            };
            m.imagery_fetches
                .get_or_create(&crate::metrics::ResultLabels { result: label })
                .inc();
        }
        result
    }

    async fn fetch(&self, t: TileCoord) -> Result<Image, ImageryError> {
        let mut backoff = Duration::from_millis(250);
        let mut attempt = 0;
        loop {
            let result = {
                let _permit = self
                    .permits
                    .acquire()
                    .await
                    .map_err(|e| ImageryError::Bad(e.to_string()))?;
                self.once(t).await
            };
            let error = match result {
                Ok(bytes) => return decode(&bytes, self.spec.tile_size),
                Err(e) => e,
            };
            let retry = matches!(error, ImageryError::Busy(_) | ImageryError::Timeout(_))
                || matches!(&error, ImageryError::Bad(m) if m.starts_with("HTTP 5"));
            if !retry || attempt >= self.spec.retries {
                return Err(error);
            }
            tokio::time::sleep(backoff.min(MAX_BACKOFF)).await;
            backoff *= 2;
            attempt += 1;
        }
    }

    async fn once(&self, t: TileCoord) -> Result<Vec<u8>, ImageryError> {
        let timeout = self.spec.timeout_s;
        // The URL may carry a key: errors never name it.
        let classify = |e: reqwest::Error| {
            if e.is_timeout() {
                ImageryError::Timeout(timeout)
            } else {
                ImageryError::Bad(e.without_url().to_string())
            }
        };
        let mut response = self.http.get(self.url(t)).send().await.map_err(classify)?;
        let status = response.status().as_u16();
        match status {
            200 => {}
            404 | 204 => return Err(ImageryError::NotFound),
            429 | 503 => return Err(ImageryError::Busy(status)),
            _ => return Err(ImageryError::Bad(format!("HTTP {status}"))),
        }
        let limit = self.spec.max_bytes;
        if response.content_length().is_some_and(|n| n > limit) {
            return Err(ImageryError::TooLarge(limit));
        }
        // Counted while streaming: a lying or missing Content-Length cannot get past the limit.
        let mut body = Vec::new();
        while let Some(chunk) = response.chunk().await.map_err(classify)? {
            if body.len() as u64 + chunk.len() as u64 > limit {
                return Err(ImageryError::TooLarge(limit));
            }
            body.extend_from_slice(&chunk);
        }
        Ok(body)
    }
}

/// Decodes PNG or JPEG bytes of exactly `size` x `size` pixels.
fn decode(bytes: &[u8], size: u32) -> Result<Image, ImageryError> {
    let bad = |detail: String| ImageryError::NotAnImage {
        expected: size,
        detail,
    };
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadkeys_follow_bing() {
        // Bing's documentation: tile (3, 5) at level 3 is quadkey "213".
        assert_eq!(quadkey(TileCoord::new(3, 3, 5).unwrap()), "213");
        assert_eq!(quadkey(TileCoord::new(0, 0, 0).unwrap()), "");
    }

    #[test]
    fn templates_fill_every_placeholder() {
        let mut spec = ImagerySpec::xyz("t", "http://h/{z}/{x}/{y}.png?tms={-y}&q={q}");
        spec.max_zoom = 19;
        let imagery = XyzImagery::new(spec).unwrap();
        let t = TileCoord::new(3, 3, 5).unwrap();
        assert_eq!(imagery.url(t), "http://h/3/3/5.png?tms=2&q=213");
    }
}

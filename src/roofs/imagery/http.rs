//! Imagery over HTTP: an XYZ tile service (`{z}/{x}/{y}`, `{-y}` for TMS rows, `{q}` for
//! quadkeys) or a WMS GetMap template (`{bbox}`, `{width}`, `{height}`), fetched politely: a
//! User-Agent, a cap on requests in flight, a timeout, retries with doubling backoff on 429, 5xx
//! and timeouts, and a size limit counted while streaming.

use super::{ImageryError, ImagerySpec};
use citymesh_core::geo::TileCoord;
use std::time::Duration;
use tokio::sync::Semaphore;

/// Longest wait between retries.
const MAX_BACKOFF: Duration = Duration::from_secs(10);

/// The coordinate system a WMS template asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WmsCrs {
    /// Web Mercator metres: a tile's box is exact.
    WebMercator,
    /// Degrees: the image is linear in latitude and is resampled to Mercator rows.
    Wgs84,
}

/// How URLs are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UrlKind {
    Xyz,
    Wms(WmsCrs),
}

impl UrlKind {
    /// A template with `{bbox}` is WMS; `EPSG:4326` (or `CRS:84`) in it asks for degrees.
    pub fn of(template: &str) -> Self {
        if !template.contains("{bbox}") && !template.contains("{bbox_yx}") {
            return UrlKind::Xyz;
        }
        let upper = template.to_ascii_uppercase().replace("%3A", ":");
        if upper.contains("EPSG:4326") || upper.contains("CRS:84") {
            UrlKind::Wms(WmsCrs::Wgs84)
        } else {
            UrlKind::Wms(WmsCrs::WebMercator)
        }
    }
}

pub struct HttpImagery {
    spec: ImagerySpec,
    kind: UrlKind,
    http: reqwest::Client,
    permits: Semaphore,
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

/// Half the Web Mercator world's width, metres.
const MERCATOR_HALF: f64 = 20_037_508.342_789_244;

impl HttpImagery {
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
            kind: UrlKind::of(&spec.url),
            spec,
            http,
        })
    }

    pub fn kind(&self) -> UrlKind {
        self.kind
    }

    /// The tile's URL from the template.
    pub fn url(&self, t: TileCoord) -> String {
        let size = self.spec.tile_size.to_string();
        match self.kind {
            UrlKind::Xyz => {
                let tms = (1u64 << t.z) - 1 - u64::from(t.y);
                self.spec
                    .url
                    .replace("{z}", &t.z.to_string())
                    .replace("{x}", &t.x.to_string())
                    .replace("{-y}", &tms.to_string())
                    .replace("{y}", &t.y.to_string())
                    .replace("{q}", &quadkey(t))
            }
            UrlKind::Wms(crs) => {
                let b = t.bounds();
                let [w, s, e, n] = match crs {
                    WmsCrs::Wgs84 => [b.min_lon(), b.min_lat(), b.max_lon(), b.max_lat()],
                    WmsCrs::WebMercator => {
                        let n = f64::from(1u32 << t.z);
                        let side = 2.0 * MERCATOR_HALF / n;
                        let west = -MERCATOR_HALF + f64::from(t.x) * side;
                        let north = MERCATOR_HALF - f64::from(t.y) * side;
                        [west, north - side, west + side, north]
                    }
                };
                self.spec
                    .url
                    .replace("{bbox}", &format!("{w},{s},{e},{n}"))
                    .replace("{bbox_yx}", &format!("{s},{w},{n},{e}"))
                    .replace("{width}", &size)
                    .replace("{height}", &size)
            }
        }
    }

    /// The tile's bytes as the service sent them (PNG or JPEG, not yet checked).
    pub async fn bytes(&self, t: TileCoord) -> Result<Vec<u8>, ImageryError> {
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
                Ok(bytes) => return Ok(bytes),
                Err(e) => e,
            };
            if !error.may_pass() || attempt >= self.spec.retries {
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
        let imagery = HttpImagery::new(spec).unwrap();
        let t = TileCoord::new(3, 3, 5).unwrap();
        assert_eq!(imagery.url(t), "http://h/3/3/5.png?tms=2&q=213");
        assert_eq!(imagery.kind(), UrlKind::Xyz);
    }

    #[test]
    fn wms_templates_get_the_tile_box_in_their_crs() {
        let t = TileCoord::new(1, 1, 0).unwrap();
        let wms = |url: &str| HttpImagery::new(ImagerySpec::xyz("w", url)).unwrap().url(t);
        // Zoom 1, column 1, row 0: the north-east quarter of the world.
        assert_eq!(
            wms("http://h/wms?SRS=EPSG:3857&BBOX={bbox}&WIDTH={width}&HEIGHT={height}"),
            format!(
                "http://h/wms?SRS=EPSG:3857&BBOX=0,0,{MERCATOR_HALF},{MERCATOR_HALF}&WIDTH=256&HEIGHT=256"
            )
        );
        let degrees = wms("http://h/wms?VERSION=1.3.0&CRS=EPSG%3A4326&BBOX={bbox_yx}");
        assert!(
            degrees.ends_with("BBOX=0,0,85.05112877980659,180"),
            "{degrees}"
        );
        assert_eq!(
            UrlKind::of("x?crs=epsg:4326&bbox={bbox}"),
            UrlKind::Wms(WmsCrs::Wgs84)
        );
    }
}

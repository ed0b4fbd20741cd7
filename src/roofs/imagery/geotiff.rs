//! Imagery from a local GeoTIFF or Cloud Optimized GeoTIFF: 8-bit RGB(A) or grey, tiled or in
//! strips, georeferenced by a tie point and a pixel scale in EPSG:4326, EPSG:3857 or a UTM zone
//! (WGS84 326xx/327xx, ETRS89 258xx). Each XYZ tile is resampled from the few TIFF tiles (chunks)
//! under it, read one by one: the file is never read whole.

use super::ImageryError;
use citymesh_core::geo::{TileCoord, UtmZone};
use citymesh_core::roof_image::{Image, srgb8_to_linear};
use std::collections::HashMap;
use std::fs::File;
use std::io::BufReader;
use std::sync::{Arc, Mutex};
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

/// Most TIFF chunks one XYZ tile may read: a tile needing more (a zoom far below the file's
/// resolution) is refused as too large rather than reading much of the file.
pub const MAX_CHUNKS_PER_TILE: usize = 64;

/// Half the Web Mercator world's width, metres.
const MERCATOR_HALF: f64 = 20_037_508.342_789_244;

/// The model space of the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crs {
    Wgs84,
    WebMercator,
    Utm(UtmZone),
}

impl Crs {
    /// From an EPSG code.
    pub fn of_epsg(code: u32) -> Option<Self> {
        match code {
            4326 => Some(Crs::Wgs84),
            3857 | 900_913 | 102_100 | 102_113 => Some(Crs::WebMercator),
            32_601..=32_660 => UtmZone::new((code - 32_600) as u8, false).map(Crs::Utm),
            32_701..=32_760 => UtmZone::new((code - 32_700) as u8, true).map(Crs::Utm),
            // ETRS89 / UTM: within a metre of WGS84 in Europe.
            25_828..=25_838 => UtmZone::new((code - 25_800) as u8, false).map(Crs::Utm),
            _ => None,
        }
    }

    /// Model coordinates of a longitude and latitude.
    pub fn project(&self, lon: f64, lat: f64) -> [f64; 2] {
        match self {
            Crs::Wgs84 => [lon, lat],
            Crs::WebMercator => {
                let y = (std::f64::consts::FRAC_PI_4 + lat.to_radians() / 2.0)
                    .tan()
                    .ln();
                [lon.to_radians() * 6_378_137.0, y * 6_378_137.0]
            }
            Crs::Utm(z) => z.project(lon, lat),
        }
    }
}

struct Raster {
    decoder: Decoder<BufReader<File>>,
    width: u32,
    height: u32,
    chunk: (u32, u32),
    chunks_across: u32,
    samples: usize,
}

pub struct GeoTiff {
    raster: Mutex<Raster>,
    crs: Crs,
    /// Model coordinates of the image's top-left corner, and of one pixel's size (x, y > 0).
    origin: [f64; 2],
    scale: [f64; 2],
    size: u32,
}

fn bad(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("not a GeoTIFF citymesh can read: {e}")
}

impl GeoTiff {
    /// Opens `path` (reading its header and georeferencing only); answers it and the zoom whose
    /// pixels match the file's at its centre.
    pub fn open(path: &std::path::Path, size: u32) -> anyhow::Result<(Arc<Self>, u8)> {
        let file = File::open(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        let mut decoder = Decoder::new(BufReader::new(file)).map_err(bad)?;
        let (width, height) = decoder.dimensions().map_err(bad)?;
        let samples = match decoder.colortype().map_err(bad)? {
            tiff::ColorType::RGB(8) => 3,
            tiff::ColorType::RGBA(8) => 4,
            tiff::ColorType::Gray(8) => 1,
            other => {
                return Err(bad(format!(
                    "{other:?} pixels (8-bit RGB, RGBA or grey only)"
                )));
            }
        };
        let chunk = decoder.chunk_dimensions();
        anyhow::ensure!(
            chunk.0 > 0 && chunk.1 > 0,
            "{}: empty chunks",
            path.display()
        );
        let scale = decoder
            .get_tag_f64_vec(Tag::Unknown(33_550))
            .map_err(|_| bad("no ModelPixelScale tag"))?;
        let tie = decoder
            .get_tag_f64_vec(Tag::Unknown(33_922))
            .map_err(|_| bad("no ModelTiepoint tag"))?;
        let keys = decoder
            .get_tag_u16_vec(Tag::Unknown(34_735))
            .map_err(|_| bad("no GeoKeyDirectory tag"))?;
        anyhow::ensure!(
            scale.len() >= 2 && tie.len() >= 6 && scale[0] > 0.0 && scale[1] > 0.0,
            "{}: unusable pixel scale or tie point",
            path.display()
        );
        let key = |id: u16| {
            keys.chunks_exact(4)
                .skip(1)
                .find(|k| k[0] == id && k[1] == 0)
                .map(|k| u32::from(k[3]))
        };
        let epsg = key(3072)
            .or_else(|| key(2048))
            .ok_or_else(|| bad("no EPSG code"))?;
        let crs = Crs::of_epsg(epsg).ok_or_else(|| {
            bad(format!(
                "EPSG:{epsg} (supported: 4326, 3857, UTM 326xx/327xx and 258xx)"
            ))
        })?;
        // Pixel-is-point rasters tie pixel centres: move to the corner.
        let half = if key(1025) == Some(2) { 0.5 } else { 0.0 };
        let origin = [
            tie[3] - (tie[0] + half) * scale[0],
            tie[4] + (tie[1] + half) * scale[1],
        ];
        let raster = Raster {
            decoder,
            width,
            height,
            chunk,
            chunks_across: width.div_ceil(chunk.0),
            samples,
        };
        let geotiff = Self {
            raster: Mutex::new(raster),
            crs,
            origin,
            scale: [scale[0], scale[1]],
            size,
        };
        let zoom = geotiff.native_zoom(height);
        Ok((Arc::new(geotiff), zoom))
    }

    /// The zoom whose pixel is no larger than the file's, at the file's centre.
    fn native_zoom(&self, height: u32) -> u8 {
        let cy = self.origin[1] - f64::from(height) / 2.0 * self.scale[1];
        // Ground metres per pixel of the file, and the latitude there.
        let (metres, lat) = match self.crs {
            Crs::Wgs84 => (self.scale[0] * 111_320.0 * cy.to_radians().cos(), cy),
            Crs::WebMercator => {
                let lat = (cy / 6_378_137.0).sinh().atan().to_degrees();
                (self.scale[0] * lat.to_radians().cos(), lat)
            }
            // Near enough for choosing a zoom: UTM northing / 111 km per degree.
            Crs::Utm(_) => (self.scale[0], cy / 110_950.0),
        };
        let world = 2.0 * MERCATOR_HALF * lat.to_radians().cos();
        let zoom = (world / (f64::from(self.size) * metres.max(1e-3)))
            .log2()
            .ceil();
        zoom.clamp(0.0, 22.0) as u8
    }

    /// The XYZ tile `t`, resampled (nearest pixel) from the file; `NotFound` when the file does
    /// not cover it at all. Blocking: file reads.
    pub fn tile(&self, t: TileCoord) -> Result<Image, ImageryError> {
        let size = self.size as usize;
        let n = f64::from(1u32 << t.z);
        let mut raster = self
            .raster
            .lock()
            .map_err(|_| ImageryError::Bad("GeoTIFF reader poisoned".into()))?;
        let (width, height) = (raster.width, raster.height);
        let mut chunks: HashMap<u32, (Vec<u8>, u32)> = HashMap::new();
        let mut pixels = vec![[0.5f32; 3]; size * size];
        let mut covered = 0usize;
        for row in 0..size {
            let y = (f64::from(t.y) + (row as f64 + 0.5) / size as f64) / n;
            let lat = (std::f64::consts::PI * (1.0 - 2.0 * y))
                .sinh()
                .atan()
                .to_degrees();
            for col in 0..size {
                let x = (f64::from(t.x) + (col as f64 + 0.5) / size as f64) / n;
                let lon = x * 360.0 - 180.0;
                let [mx, my] = self.crs.project(lon, lat);
                let px = (mx - self.origin[0]) / self.scale[0];
                let py = (self.origin[1] - my) / self.scale[1];
                if !(px >= 0.0 && py >= 0.0 && px < f64::from(width) && py < f64::from(height)) {
                    continue;
                }
                let (px, py) = (px as u32, py as u32);
                let (cw, ch) = raster.chunk;
                let index = (py / ch) * raster.chunks_across + px / cw;
                if !chunks.contains_key(&index) {
                    if chunks.len() >= MAX_CHUNKS_PER_TILE {
                        return Err(ImageryError::TooLarge(MAX_CHUNKS_PER_TILE as u64));
                    }
                    let stride = raster.decoder.chunk_data_dimensions(index).0;
                    let data = match raster.decoder.read_chunk(index) {
                        Ok(DecodingResult::U8(data)) => data,
                        Ok(_) => return Err(ImageryError::Bad("GeoTIFF: not 8-bit".into())),
                        Err(e) => return Err(ImageryError::Bad(format!("GeoTIFF: {e}"))),
                    };
                    chunks.insert(index, (data, stride));
                }
                let Some((data, stride)) = chunks.get(&index) else {
                    continue;
                };
                let (lx, ly) = ((px % cw) as usize, (py % ch) as usize);
                let at = (ly * *stride as usize + lx) * raster.samples;
                let Some(p) = data.get(at..at + raster.samples) else {
                    continue;
                };
                let rgb = if raster.samples == 1 {
                    [p[0]; 3]
                } else {
                    [p[0], p[1], p[2]]
                };
                pixels[row * size + col] = rgb.map(srgb8_to_linear);
                covered += 1;
            }
        }
        if covered == 0 {
            return Err(ImageryError::NotFound);
        }
        Ok(Image {
            width: size,
            height: size,
            pixels,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tiff::encoder::{TiffEncoder, colortype};

    /// Writes an RGB GeoTIFF in strips of 16 rows: `pixel(col, row)` gives each colour.
    pub(crate) fn write_geotiff(
        path: &std::path::Path,
        (width, height): (u32, u32),
        epsg: u16,
        origin: [f64; 2],
        scale: f64,
        pixel: impl Fn(u32, u32) -> [u8; 3],
    ) {
        let file = File::create(path).unwrap();
        let mut encoder = TiffEncoder::new(file).unwrap();
        let mut image = encoder.new_image::<colortype::RGB8>(width, height).unwrap();
        image.rows_per_strip(16).unwrap();
        let dir = image.encoder();
        dir.write_tag(Tag::Unknown(33_550), &[scale, scale, 0.0][..])
            .unwrap();
        dir.write_tag(
            Tag::Unknown(33_922),
            &[0.0, 0.0, 0.0, origin[0], origin[1], 0.0][..],
        )
        .unwrap();
        let projected = epsg != 4326;
        let (model, key) = if projected { (1, 3072) } else { (2, 2048) };
        dir.write_tag(
            Tag::Unknown(34_735),
            &[
                1u16, 1, 0, 3, 1024, 0, 1, model, 1025, 0, 1, 1, key, 0, 1, epsg,
            ][..],
        )
        .unwrap();
        let mut data = Vec::with_capacity((width * height * 3) as usize);
        for row in 0..height {
            for col in 0..width {
                data.extend_from_slice(&pixel(col, row));
            }
        }
        image.write_data(&data).unwrap();
    }

    #[test]
    fn a_utm_raster_lands_where_its_coordinates_say() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("utm.tif");
        let zone = UtmZone::new(32, false).unwrap();
        // 200 x 200 m at 1 m per pixel, its top-left corner at a round point in Karlsruhe: red
        // west of easting +100 m, blue east of it.
        let [e0, n0] = zone.project(8.40, 49.01).map(f64::round);
        write_geotiff(&path, (200, 200), 32_632, [e0, n0], 1.0, |col, _| {
            if col < 100 { [255, 0, 0] } else { [0, 0, 255] }
        });
        let (file, zoom) = GeoTiff::open(&path, 256).unwrap();
        // 1 m pixels: zoom 17 has 0.78 m pixels at 49 N, zoom 16 1.57 m.
        assert_eq!(zoom, 17);
        let t = TileCoord::covering(
            &citymesh_core::geo::GeoBbox::new(8.4005, 49.0095, 8.4006, 49.0096).unwrap(),
            18,
        )
        .tiles()
        .next()
        .unwrap();
        let image = file.tile(t).unwrap();
        let n = f64::from(1u32 << t.z);
        let (mut red, mut blue) = (0, 0);
        for row in (0..256).step_by(7) {
            for col in (0..256).step_by(7) {
                let lon = (f64::from(t.x) + (col as f64 + 0.5) / 256.0) / n * 360.0 - 180.0;
                let y = (f64::from(t.y) + (row as f64 + 0.5) / 256.0) / n;
                let lat = (std::f64::consts::PI * (1.0 - 2.0 * y))
                    .sinh()
                    .atan()
                    .to_degrees();
                let [e, nn] = zone.project(lon, lat);
                let (dx, dy) = (e - e0, n0 - nn);
                let p = image.get(col, row);
                // Away from the edges (half a pixel of rounding), the colour is the raster's.
                if (1.0..199.0).contains(&dx)
                    && (1.0..199.0).contains(&dy)
                    && (dx - 100.0).abs() > 1.0
                {
                    if dx < 100.0 {
                        assert_eq!(p, [1.0, 0.0, 0.0], "{col} {row}");
                        red += 1;
                    } else {
                        assert_eq!(p, [0.0, 0.0, 1.0], "{col} {row}");
                        blue += 1;
                    }
                } else if !(-1.0..=201.0).contains(&dx) || !(-1.0..=201.0).contains(&dy) {
                    assert_eq!(p, [0.5; 3], "outside: {col} {row}");
                }
            }
        }
        assert!(red > 50 && blue > 50, "{red} {blue}");
        // A tile the raster does not reach.
        let far = TileCoord::new(18, t.x + 20, t.y).unwrap();
        assert!(matches!(file.tile(far), Err(ImageryError::NotFound)));
        // Not a GeoTIFF, and an unsupported CRS.
        let junk = dir.path().join("junk.tif");
        std::fs::write(&junk, b"II*\0garbage").unwrap();
        assert!(GeoTiff::open(&junk, 256).is_err());
        let odd = dir.path().join("odd.tif");
        write_geotiff(&odd, (16, 16), 2154, [0.0, 0.0], 1.0, |_, _| [0; 3]);
        let e = GeoTiff::open(&odd, 256).err().unwrap().to_string();
        assert!(e.contains("EPSG:2154"), "{e}");
    }
}

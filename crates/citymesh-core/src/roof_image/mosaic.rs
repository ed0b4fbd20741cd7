//! Crops from Web Mercator imagery tiles (XYZ): the zoom a crop needs, the tiles it covers, and
//! the crop rule applied to the stitched tiles (paper Figure 14: tiles concatenated, then cut).

use super::crop::{Crop, CropFrame, CropRule};
use super::image::Image;
use crate::geo::{GeoBbox, LocalFrame, TileCoord, TileRange, mercator_y};

/// Metres per pixel at the equator at zoom 0 for 256-pixel tiles.
const EQUATOR_M_PER_PX: f64 = 156_543.033_928;

/// A footprint ready to be cropped: its local frame (origin at the footprint's first node), its
/// outer ring in metres there, and its crop frame by the rule.
#[derive(Debug, Clone)]
pub struct FootprintCrop {
    pub local: LocalFrame,
    pub outer: Vec<[f64; 2]>,
    pub frame: CropFrame,
}

impl FootprintCrop {
    /// `None` when the ring has no extent.
    pub fn new(outer_lon_lat: &[[f64; 2]], rule: CropRule) -> Option<Self> {
        let first = outer_lon_lat.first()?;
        let local = LocalFrame::new(first[0], first[1], 0.0);
        let outer: Vec<[f64; 2]> = outer_lon_lat
            .iter()
            .map(|p| {
                let q = local.to_local(p[0], p[1], 0.0);
                [q[0], q[1]]
            })
            .collect();
        let frame = CropFrame::of_footprint(&outer, rule)?;
        Some(Self {
            local,
            outer,
            frame,
        })
    }

    /// The ground box of the crop in degrees.
    pub fn bounds(&self) -> Option<GeoBbox> {
        let [lo, hi] = self.frame.bounds();
        let (w, s, _) = self.local.to_geographic([lo[0], lo[1], 0.0]);
        let (e, n, _) = self.local.to_geographic([hi[0], hi[1], 0.0]);
        GeoBbox::new(w, s, e, n).ok()
    }

    /// The zoom whose pixels are at least as fine as the crop's, at most `max_zoom`.
    pub fn zoom(&self, tile_size: u32, max_zoom: u8) -> u8 {
        let (_, lat, _) = self.local.origin();
        let scale = 256.0 / f64::from(tile_size.max(1));
        (0..=max_zoom)
            .find(|&z| ground_resolution(lat, z) * scale <= self.frame.metres_per_pixel)
            .unwrap_or(max_zoom)
    }

    /// The tiles of `zoom` under the crop.
    pub fn tiles(&self, zoom: u8) -> Option<TileRange> {
        Some(TileCoord::covering(&self.bounds()?, zoom))
    }

    /// The crop from the tiles of `range` (each `tile_size` pixels square, in linear light; a
    /// missing tile is drawn black), with the footprint mask.
    pub fn crop(&self, range: &TileRange, tile_size: usize, tiles: &[(TileCoord, &Image)]) -> Crop {
        let cols = (range.x1 - range.x0 + 1) as usize;
        let rows = (range.y1 - range.y0 + 1) as usize;
        let mut mosaic = Image::filled(cols * tile_size, rows * tile_size, [0.0; 3]);
        for (coord, image) in tiles {
            if !range.contains(coord) || image.width != tile_size || image.height != tile_size {
                continue;
            }
            let ox = (coord.x - range.x0) as usize * tile_size;
            let oy = (coord.y - range.y0) as usize * tile_size;
            for y in 0..tile_size {
                let row = &image.pixels[y * tile_size..(y + 1) * tile_size];
                let start = (oy + y) * mosaic.width + ox;
                mosaic.pixels[start..start + tile_size].copy_from_slice(row);
            }
        }
        let n = (1u64 << range.z) as f64 * tile_size as f64;
        let origin = [
            f64::from(range.x0) * tile_size as f64,
            f64::from(range.y0) * tile_size as f64,
        ];
        let to_pixel = |w: [f64; 2]| {
            let (lon, lat, _) = self.local.to_geographic([w[0], w[1], 0.0]);
            [
                (lon + 180.0) / 360.0 * n - origin[0],
                mercator_y(lat) * n - origin[1],
            ]
        };
        let (_, lat, _) = self.local.origin();
        let source = ground_resolution(lat, range.z) * 256.0 / tile_size as f64;
        Crop {
            size: self.frame.size,
            rgb: self.frame.sample(&mosaic, to_pixel, source),
            mask: Some(self.frame.mask(std::slice::from_ref(&self.outer))),
        }
    }
}

/// Ground metres per pixel of 256-pixel tiles at `zoom` and latitude `lat`.
pub fn ground_resolution(lat: f64, zoom: u8) -> f64 {
    EQUATOR_M_PER_PX * lat.to_radians().cos() / (1u64 << zoom) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ground_resolution_matches_the_published_figures() {
        // 156543.03 * cos(49 deg) / 2^19 = 0.1959 m/px.
        assert!((ground_resolution(49.0, 19) - 0.1959).abs() < 1e-4);
        assert!((ground_resolution(0.0, 0) - 156_543.033_928).abs() < 1e-6);
    }

    #[test]
    fn a_house_is_cropped_from_the_right_tiles_at_the_right_zoom() {
        // A 16 x 10 m house at Karlsruhe: 16 m over 0.8 * 96 px = 0.208 m/px: zoom 19 (0.196) is
        // the first at least that fine; z18 (0.39) is coarser.
        let frame = LocalFrame::new(8.4, 49.0, 0.0);
        let ring: Vec<[f64; 2]> = [[0.0, 0.0], [16.0, 0.0], [16.0, 10.0], [0.0, 10.0]]
            .iter()
            .map(|p| {
                let (lon, lat, _) = frame.to_geographic([p[0], p[1], 0.0]);
                [lon, lat]
            })
            .collect();
        let fc = FootprintCrop::new(&ring, CropRule::MODEL).expect("a crop");
        assert_eq!(fc.zoom(256, 20), 19);
        assert_eq!(fc.zoom(256, 18), 18);
        assert_eq!(fc.zoom(512, 20), 18);
        let range = fc.tiles(19).expect("tiles");
        assert!(range.len() <= 4, "{range:?}");

        // Tiles painted by their column: the crop's left half must come from western tiles.
        let tiles: Vec<(TileCoord, Image)> = range
            .tiles()
            .map(|t| {
                let shade = (t.x - range.x0) as f32 * 0.5 + 0.2;
                (t, Image::filled(256, 256, [shade; 3]))
            })
            .collect();
        let refs: Vec<(TileCoord, &Image)> = tiles.iter().map(|(t, i)| (*t, i)).collect();
        let crop = fc.crop(&range, 256, &refs);
        let mask = crop.mask.expect("mask");
        // 16 m at 0.208 m/px: 77 columns of 96 inside.
        let cols = (0..96).filter(|&x| mask[48 * 96 + x] == 255).count();
        assert!((76..=78).contains(&cols), "{cols}");
        // No pixel is black: every tile the crop touches was given.
        assert!(crop.rgb.iter().all(|p| p[0] > 0));
    }
}

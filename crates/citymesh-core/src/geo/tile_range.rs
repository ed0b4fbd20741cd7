//! A rectangle of XYZ tiles of one zoom: the tiles covering an area, e.g. the OSM data tiles an
//! area needs.

use super::{GeoBbox, TileCoord};

/// The tiles `x0..=x1` by `y0..=y1` of zoom `z` (inclusive; `y` counts from the north).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TileRange {
    pub z: u8,
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
}

impl TileCoord {
    /// The tiles of zoom `z` that cover `bbox` (its border included).
    ///
    /// ```
    /// use citymesh_core::geo::{GeoBbox, TileCoord};
    /// let palace = TileCoord::new(16, 34_297, 22_502).unwrap();
    /// let r = TileCoord::covering(&palace.bounds(), 14);
    /// assert_eq!((r.x0, r.x1, r.y0, r.y1), (8574, 8574, 5625, 5625));
    /// ```
    pub fn covering(bbox: &GeoBbox, z: u8) -> TileRange {
        let nw = TileCoord::containing(z, bbox.min_lon(), bbox.max_lat());
        let se = TileCoord::containing(z, bbox.max_lon(), bbox.min_lat());
        TileRange {
            z,
            x0: nw.x,
            x1: se.x,
            y0: nw.y,
            y1: se.y,
        }
    }
}

impl TileRange {
    /// Whether the tile is one of the range.
    pub fn contains(&self, t: &TileCoord) -> bool {
        t.z == self.z && (self.x0..=self.x1).contains(&t.x) && (self.y0..=self.y1).contains(&t.y)
    }

    /// The number of tiles.
    pub fn len(&self) -> u64 {
        (u64::from(self.x1) - u64::from(self.x0) + 1)
            * (u64::from(self.y1) - u64::from(self.y0) + 1)
    }

    /// Always false: a range holds at least one tile.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The tiles, row by row from the north-west.
    pub fn tiles(&self) -> impl Iterator<Item = TileCoord> + use<> {
        let (z, x0, x1) = (self.z, self.x0, self.x1);
        (self.y0..=self.y1).flat_map(move |y| (x0..=x1).map(move |x| TileCoord { z, x, y }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_on_a_tile_corner_needs_four() {
        let corner = TileCoord::new(14, 8574, 5625).unwrap().bounds();
        // A tiny box around the tile's north-west corner.
        let b = GeoBbox::new(
            corner.min_lon() - 1e-6,
            corner.max_lat() - 1e-6,
            corner.min_lon() + 1e-6,
            corner.max_lat() + 1e-6,
        )
        .unwrap();
        let r = TileCoord::covering(&b, 14);
        assert_eq!((r.x0, r.x1, r.y0, r.y1), (8573, 8574, 5624, 5625));
        assert_eq!(r.len(), 4);
        let tiles: Vec<_> = r.tiles().map(|t| (t.x, t.y)).collect();
        assert_eq!(
            tiles,
            [(8573, 5624), (8574, 5624), (8573, 5625), (8574, 5625)]
        );
        assert!(r.contains(&TileCoord {
            z: 14,
            x: 8574,
            y: 5624
        }));
        assert!(!r.contains(&TileCoord {
            z: 15,
            x: 8574,
            y: 5624
        }));
        assert!(!r.contains(&TileCoord {
            z: 14,
            x: 8575,
            y: 5624
        }));
    }
}

//! The implicit quadtree of 3D Tiles 1.1 over a geographic region: each level halves the region
//! linearly in longitude and latitude, with `y` counted from the south (unlike XYZ tiles), and
//! availability bitstreams list tiles in Morton order.

use super::{BboxError, GeoBbox, LocalFrame};

/// Content tiles are at most this wide (metres).
pub const LEAF_SIZE_M: f64 = 400.0;

/// A tile of the implicit quadtree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImplicitTile {
    pub level: u8,
    pub x: u32,
    pub y: u32,
}

impl ImplicitTile {
    /// The level whose tiles over `root` are at most [`LEAF_SIZE_M`] wide (where content is):
    /// it depends on the region alone.
    pub fn leaf_level(root: &GeoBbox) -> u8 {
        let (lon, lat) = root.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        let side =
            ((root.max_lon() - root.min_lon()) * mx).max((root.max_lat() - root.min_lat()) * my);
        (side / LEAF_SIZE_M).log2().ceil().clamp(0.0, 12.0) as u8
    }

    /// Whether the coordinates exist at the level.
    pub fn is_valid(&self) -> bool {
        self.level < 31
            && u64::from(self.x) < (1u64 << self.level)
            && u64::from(self.y) < (1u64 << self.level)
    }

    /// The tile's part of `root`: `[west, south, east, north]` degrees.
    pub fn bounds(&self, root: &GeoBbox) -> [f64; 4] {
        let n = f64::from(1u32 << self.level);
        let dx = (root.max_lon() - root.min_lon()) / n;
        let dy = (root.max_lat() - root.min_lat()) / n;
        [
            root.min_lon() + dx * f64::from(self.x),
            root.min_lat() + dy * f64::from(self.y),
            root.min_lon() + dx * f64::from(self.x + 1),
            root.min_lat() + dy * f64::from(self.y + 1),
        ]
    }

    /// The tile's part of `root` as a box (an error only when the tile is too small for
    /// distinct degrees).
    pub fn bbox(&self, root: &GeoBbox) -> Result<GeoBbox, BboxError> {
        let [w, s, e, n] = self.bounds(root);
        GeoBbox::new(w, s, e, n)
    }

    /// The tile at `level` that holds a point of `root`; points on an inner edge belong to the
    /// tile east or north of it, those on the root's east or north edge to the last tile.
    pub fn containing(root: &GeoBbox, level: u8, lon: f64, lat: f64) -> Self {
        let n = 1u32 << level;
        let fx = (lon - root.min_lon()) / (root.max_lon() - root.min_lon());
        let fy = (lat - root.min_lat()) / (root.max_lat() - root.min_lat());
        let clamp = |f: f64| ((f * f64::from(n)).floor().max(0.0) as u32).min(n - 1);
        Self {
            level,
            x: clamp(fx),
            y: clamp(fy),
        }
    }
}

/// The Morton (Z-order) index: bits of `x` in even positions, of `y` in odd ones.
pub fn morton(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = u64::from(v);
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    };
    spread(x) | (spread(y) << 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_x_then_y() {
        assert_eq!(morton(0, 0), 0);
        assert_eq!(morton(1, 0), 1);
        assert_eq!(morton(0, 1), 2);
        assert_eq!(morton(1, 1), 3);
        assert_eq!(morton(2, 0), 4);
        assert_eq!(morton(3, 5), 0b10_0111);
    }

    #[test]
    fn y_counts_from_the_south() {
        let root = GeoBbox::new(8.0, 49.0, 9.0, 50.0).unwrap();
        let t = ImplicitTile::containing(&root, 1, 8.2, 49.9);
        assert_eq!((t.x, t.y), (0, 1));
        assert_eq!(t.bounds(&root), [8.0, 49.5, 8.5, 50.0]);
        assert_eq!(
            ImplicitTile::containing(&root, 2, 9.0, 50.0),
            ImplicitTile {
                level: 2,
                x: 3,
                y: 3
            }
        );
    }
}

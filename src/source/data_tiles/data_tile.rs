//! Data tiles: OSM data is fetched and stored per Web Mercator tile of one fixed zoom.
//!
//! Zoom 14: a data tile is about 2.4 km across at the equator and 1.6 km at 49° N. One Overpass
//! query for it returns a few thousand buildings in a dense city (a few MB of JSON, seconds of
//! Overpass time, well inside its default limits), while every served tile from zoom 14 up lies
//! in one data tile (and its neighbours where buildings reach over the edge). Coarser data tiles
//! would make single queries slow and heavy; finer ones would multiply queries for a city view.

use citymesh_core::geo::{GeoBbox, TileCoord};

/// The zoom of data tiles.
pub const DATA_ZOOM: u8 = 14;

/// Most data tiles one request may need: a square of the largest default area (25 km²) needs at
/// most 25 with its margin; longer boxes would make one request cost many upstream calls.
pub const MAX_DATA_TILES: usize = 36;

/// How far (degrees, about 200 m) around an area data is loaded, so buildings and groups of
/// buildings reaching over a tile edge are complete.
pub const MARGIN_DEGREES: f64 = 0.002;

/// The data tiles an area needs, with the margin, column by column from the west.
pub fn data_tiles_for(bbox: &GeoBbox) -> Vec<TileCoord> {
    let mut tiles: Vec<TileCoord> =
        TileCoord::covering(&bbox.grown_by_degrees(MARGIN_DEGREES), DATA_ZOOM)
            .tiles()
            .collect();
    tiles.sort_unstable();
    tiles
}

/// The area whose served tiles may use a data tile: its bounds grown by the margin.
pub fn affected_area(data_tile: &TileCoord) -> GeoBbox {
    data_tile.bounds().grown_by_degrees(MARGIN_DEGREES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tile_inside_a_data_tile_needs_just_that_one() {
        // A z16 tile in the middle of data tile 14/8573/5621 (Karlsruhe-Neureut).
        let t = TileCoord::new(16, 34294, 22486).unwrap();
        let d = data_tiles_for(&t.bounds());
        assert_eq!(
            d,
            vec![TileCoord {
                z: 14,
                x: 8573,
                y: 5621
            }]
        );
        // One on its corner needs the four around the corner.
        let corner = TileCoord::new(16, 34292, 22484).unwrap();
        assert_eq!(data_tiles_for(&corner.bounds()).len(), 4);
    }
}

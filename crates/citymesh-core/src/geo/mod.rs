//! Geographic frames and tile math: validated bounding boxes, the local metric frame every scene is
//! built in, Web Mercator XYZ tiles, ECEF coordinates and the implicit quadtree of 3D Tiles.

mod bbox;
mod ecef;
mod implicit;
mod local_frame;
mod region;
mod tile;
mod tile_range;
mod utm;
mod wkt;

pub use bbox::{BboxError, GeoBbox, MAX_MERCATOR_LAT};
pub use ecef::{ecef_to_geodetic, geodetic_to_ecef};
pub use implicit::{ImplicitTile, LEAF_SIZE_M, morton};
pub use local_frame::{LocalFrame, WGS84_A, WGS84_E2};
pub use region::Region;
pub use tile::{MAX_ZOOM, TileCoord, TileError, mercator_y};
pub use tile_range::TileRange;
pub use utm::UtmZone;
pub use wkt::parse_wkt_polygon;

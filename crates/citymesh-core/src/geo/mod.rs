//! Geographic frames and tile math: validated bounding boxes, the local metric frame every scene is
//! built in, and Web Mercator XYZ tiles.

mod bbox;
mod local_frame;
mod tile;

pub use bbox::{BboxError, GeoBbox, MAX_MERCATOR_LAT};
pub use local_frame::{LocalFrame, WGS84_A, WGS84_E2};
pub use tile::{MAX_ZOOM, TileCoord, TileError};

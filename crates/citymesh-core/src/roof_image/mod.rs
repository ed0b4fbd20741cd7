//! Top-down images of roofs for the roof-shape classifier (docs/extensions.md section 1).
//!
//! [`render`] draws citymesh's own meshes orthographically from above (optionally off nadir), lit
//! by a sun with cast shadows, into an [`Image`]; [`crop`] is the crop rule that turns imagery
//! around one footprint into the classifier's input, used for training renders and run-time
//! imagery alike; [`synthetic`] builds randomised training scenes (roofs, clutter, trees,
//! neighbours, camera and sensor effects, [`jpeg`] artefacts) from real or procedural footprints;
//! [`class`] names the three classes the model predicts.

pub mod class;
pub mod crop;
mod image;
pub mod jpeg;
pub mod mosaic;
mod noise;
pub mod png_metadata;
pub mod render;
pub mod synthetic;

pub use class::RoofClass;
pub use crop::{Crop, CropFrame, CropRule};
pub use image::{Image, srgb8_to_linear};
pub use render::{Camera, Sun};

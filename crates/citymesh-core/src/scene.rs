//! A scene: everything generated for one bounding box, in one local frame, ready to encode.

use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{GlbOrigin, Mesh, write_glb};
use crate::terrain::{ElevationModel, GroundReport, build_ground};

/// The generated mesh of a bounding box and what went into it.
#[derive(Debug, Clone)]
pub struct Scene {
    pub frame: LocalFrame,
    pub mesh: Mesh,
    pub ground: GroundReport,
}

impl Scene {
    /// The ground of `bbox` from `model`, in a frame whose origin is the box centre at 0 m
    /// (mean sea level), so all tiles and scenes share one height reference.
    pub fn ground(model: &ElevationModel, bbox: &GeoBbox) -> Self {
        let (lon, lat) = bbox.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let mut mesh = Mesh::default();
        let ground = build_ground(model, bbox, &frame, &mut mesh);
        Self {
            frame,
            mesh,
            ground,
        }
    }

    /// The scene as GLB bytes, with its origin recorded in the file.
    pub fn to_glb(&self) -> Vec<u8> {
        let (lon, lat, height) = self.frame.origin();
        write_glb(&self.mesh, GlbOrigin { lon, lat, height })
    }
}

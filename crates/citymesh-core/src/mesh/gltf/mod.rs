//! glTF 2.0 binary (GLB) encoding of a [`Mesh`], in four stages that each own one concern:
//!
//! 1. [`placement`]: where the mesh sits on the Earth. Local east/north/up metres become the
//!    file's axes: glTF's y-up local frame, or Earth-centred (ECEF) coordinates for 3D Tiles. All
//!    geodesy happens here.
//! 2. [`layout`]: the indexed vertex layout. One primitive per [`super::Material`]; a vertex is
//!    shared by the triangles of one planar face (same corner, colour and normal), so a wall quad
//!    is 4 vertices and 6 indices, and faces stay flat shaded.
//! 3. [`document`]: the glTF JSON, assembled with `gltf-json`, and the binary buffer.
//! 4. [`container`]: the GLB container (header, JSON chunk, BIN chunk).

mod container;
mod document;
mod layout;
mod placement;

pub use container::write_container_with;
pub use layout::{IndexedLayout, LayoutPrimitive};
pub use placement::{Placed, Placement, place};

use super::Mesh;
use crate::geo::LocalFrame;

/// An encoded GLB and the figures of what it holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EncodedGlb {
    pub bytes: Vec<u8>,
    /// Vertices in the file (after sharing within faces).
    pub vertices: usize,
    /// Triangles in the file (degenerate ones are left out).
    pub triangles: usize,
}

/// Encodes `mesh`, built in `frame`, with the given placement. `buildings` (OSM ids such as
/// `way/123`) are listed in `scenes[0].extras.buildings`.
pub fn encode_glb(
    mesh: &Mesh,
    frame: &LocalFrame,
    placement: Placement,
    buildings: &[String],
) -> EncodedGlb {
    let placed = place(mesh, frame, placement);
    let layout = IndexedLayout::new(mesh, &placed.positions);
    let (vertices, triangles) = (layout.vertex_count(), layout.triangle_count());
    let json = document::assemble(&layout, &placed, buildings);
    let bytes = write_container_with(json, document::binary_len(&layout), |out| {
        document::write_binary(&layout, out);
    });
    EncodedGlb {
        bytes,
        vertices,
        triangles,
    }
}

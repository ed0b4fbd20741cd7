//! glTF 2.0 binary (GLB) encoding of a [`Mesh`], in stages that each own one concern:
//!
//! 1. [`placement`]: where the mesh sits on the Earth. Local east/north/up metres become the
//!    file's axes: glTF's y-up local frame, or Earth-centred (ECEF) coordinates for 3D Tiles. All
//!    geodesy happens here.
//! 2. [`quantize`]: positions as the [`Encoding`] stores them: f32 metres, or u16 steps in a box.
//! 3. [`layout`]: the indexed vertex layout. One primitive per [`super::Material`]; vertices
//!    welded by stored position and shared within a face (or, without normals, by every face
//!    of a colour); for `meshopt`, reordered by [`meshopt`] for its codecs.
//! 4. [`document`]: the glTF JSON and the binary buffer in the encoding, with the features'
//!    property table from [`metadata`].
//! 5. [`container`]: the GLB container (header, JSON chunk, BIN chunk).
//!
//! Normals are stored for Earth-centred content only: CesiumJS, which loads 3D Tiles, lights a
//! primitive without normals as unlit, while three.js (and every client following the glTF
//! specification) computes flat normals itself, so local-frame files leave them out.

mod container;
mod document;
mod encoding;
mod layout;
mod meshopt;
pub mod metadata;
mod placement;
mod quantize;

pub use container::write_container_with;
pub use encoding::{Encoding, UnknownEncoding};
pub use layout::{IndexedLayout, LayoutPrimitive};
pub use metadata::{ClassDef, Column, PropertyDef, PropertyTable, PropertyType};
pub use placement::{NodePlacement, Placed, Placement, local_axes, node_placement, place};
pub use quantize::{Quantization, Stored, store};

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

/// Encodes `mesh`, built in `frame`, with the given placement and encoding. `buildings` (OSM
/// ids such as `way/123`) are listed in `scenes[0].extras.buildings`; `features` holds a row per
/// feature the mesh's triangles name.
pub fn encode_glb(
    mesh: &Mesh,
    frame: &LocalFrame,
    placement: Placement,
    encoding: Encoding,
    buildings: &[String],
    features: Option<&PropertyTable>,
) -> EncodedGlb {
    // Local files: positions are the mesh's, turned to glTF axes on the way into storage.
    // Earth-centred ones: placed first, and the placed positions give the normals they store.
    let (stored, ecef, node) = match placement {
        Placement::LocalEnu => {
            let node = node_placement(frame, placement);
            let stored = store(mesh.positions.iter().map(|&p| local_axes(p)), encoding);
            (stored, None, node)
        }
        Placement::Ecef => {
            let placed = place(mesh, frame, placement);
            let stored = store(placed.positions.iter().copied(), encoding);
            (stored, Some(placed.positions), placed.node)
        }
    };
    let mut layout = IndexedLayout::new(mesh, &stored.positions, ecef.as_deref());
    if encoding == Encoding::Meshopt {
        layout.primitives.iter_mut().for_each(meshopt::reorder);
    }
    let (vertices, triangles) = (layout.vertex_count(), layout.triangle_count());
    let doc = document::assemble(
        &layout,
        &node,
        stored.quantization,
        encoding,
        buildings,
        features,
    );
    let bytes = write_container_with(doc.json, doc.bin.len(), |out| {
        out.extend_from_slice(&doc.bin);
    });
    EncodedGlb {
        bytes,
        vertices,
        triangles,
    }
}

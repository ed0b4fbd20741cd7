//! Stage 1 of the encoder: from the mesh's local east/north/up metres to the file's axes.
//!
//! glTF is y-up, so the local placement maps (east, north, up) to (x, y, z) = (east, up, -north),
//! a proper rotation that keeps counter-clockwise triangles counter-clockwise; the frame's origin
//! is recorded in the file. 3D Tiles content is Earth-centred: positions become ECEF metres
//! relative to the scene centre's ECEF point (kept small, so f32 keeps millimetres), z-up, and the
//! node carries the centre and the z-up to y-up turn (a 3D Tiles client applies the standard
//! y-up to z-up transform and gets ECEF back).

use crate::geo::{LocalFrame, geodetic_to_ecef};
use crate::mesh::Mesh;

/// How a mesh is placed in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Placement {
    /// glTF y-up axes around the frame's origin, recorded in `scenes[0].extras.origin`.
    LocalEnu,
    /// 3D Tiles content: ECEF relative to the frame origin's ECEF point, under a node matrix.
    Ecef,
}

/// Positions in the file's axes and what the file must record to place them.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// One per mesh vertex, relative to the node.
    pub positions: Vec<[f64; 3]>,
    pub node: NodePlacement,
}

/// What the file records about its placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NodePlacement {
    /// The local frame's origin: longitude, latitude (degrees), height (metres above sea level).
    Origin { lon: f64, lat: f64, height: f64 },
    /// The ECEF point (metres) the positions are relative to.
    EcefCentre([f64; 3]),
}

/// A local east/north/up position in glTF's y-up axes: (east, up, -north).
#[inline]
pub fn local_axes(p: [f64; 3]) -> [f64; 3] {
    [p[0], p[2], -p[1]]
}

/// What the file records for content built in `frame` with `placement`.
pub fn node_placement(frame: &LocalFrame, placement: Placement) -> NodePlacement {
    let (lon, lat, height) = frame.origin();
    match placement {
        Placement::LocalEnu => NodePlacement::Origin { lon, lat, height },
        // The centre at 0 m: every scene shares the height reference of its frame.
        Placement::Ecef => NodePlacement::EcefCentre(geodetic_to_ecef(lon, lat, 0.0)),
    }
}

/// Places every vertex of `mesh`, built in `frame`.
pub fn place(mesh: &Mesh, frame: &LocalFrame, placement: Placement) -> Placed {
    let node = node_placement(frame, placement);
    match node {
        NodePlacement::Origin { .. } => Placed {
            positions: mesh.positions.iter().map(|&p| local_axes(p)).collect(),
            node,
        },
        NodePlacement::EcefCentre(c) => {
            let positions = mesh
                .positions
                .iter()
                .map(|&p| {
                    let (lon, lat, h) = frame.to_geographic(p);
                    let e = geodetic_to_ecef(lon, lat, h);
                    [e[0] - c[0], e[1] - c[1], e[2] - c[2]]
                })
                .collect();
            Placed { positions, node }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceStyle, Material, Rgb};

    fn one_vertex(p: [f64; 3]) -> Mesh {
        let mut m = Mesh::default();
        m.push_vertex(p);
        m.push_triangle([0, 0, 0], FaceStyle::plain(Material::Wall, Rgb::GROUND));
        m
    }

    #[test]
    fn local_axes_are_east_up_minus_north() {
        let frame = LocalFrame::new(8.4, 49.0, 0.0);
        let placed = place(&one_vertex([1.0, 2.0, 3.0]), &frame, Placement::LocalEnu);
        assert_eq!(placed.positions, [[1.0, 3.0, -2.0]]);
        assert_eq!(
            placed.node,
            NodePlacement::Origin {
                lon: 8.4,
                lat: 49.0,
                height: 0.0
            }
        );
    }

    #[test]
    fn ecef_is_relative_to_the_centre() {
        let frame = LocalFrame::new(8.4, 49.0, 0.0);
        // 100 m up from the origin: along the ellipsoid normal there.
        let placed = place(&one_vertex([0.0, 0.0, 100.0]), &frame, Placement::Ecef);
        let [x, y, z] = placed.positions[0];
        let (lon, lat) = (8.4f64.to_radians(), 49.0f64.to_radians());
        let normal = [lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()];
        for (got, n) in [x, y, z].into_iter().zip(normal) {
            assert!((got - 100.0 * n).abs() < 1e-6, "{got} vs {}", 100.0 * n);
        }
        assert_eq!(
            placed.node,
            NodePlacement::EcefCentre(geodetic_to_ecef(8.4, 49.0, 0.0))
        );
    }
}

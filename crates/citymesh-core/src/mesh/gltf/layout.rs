//! Stage 2 of the encoder: the indexed vertex layout.
//!
//! Faces are flat shaded: every vertex carries its face's normal and colour. A vertex is shared
//! by the triangles that meet at one mesh corner with the same colour and the same normal
//! (quantised to [`NORMAL_STEPS`] steps per unit, so rounding noise between the triangles of one
//! plane does not split them), which are the triangles of one planar face: a wall quad becomes 4
//! vertices instead of 6, a flat roof of n triangles about n + 2. Triangles with no area (in
//! f64, or once rounded to f32) are left out, since they have no normal.

use crate::mesh::{Material, Mesh, triangle_normal};

/// Normals are compared in steps of 1/16384 per component (about 0.0035 degrees): far below any
/// visible crease, far above the rounding noise between triangles of one plane.
const NORMAL_STEPS: f32 = 16_384.0;

/// One primitive: a material's vertices and triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LayoutPrimitive {
    pub material: Option<Material>,
    /// Positions in file axes, f32.
    pub positions: Vec<[f32; 3]>,
    /// Unit face normals.
    pub normals: Vec<[f32; 3]>,
    /// Linear RGBA colours.
    pub colours: Vec<[u8; 4]>,
    /// Three per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

/// The primitives of a mesh, one per material present, in [`Material::ALL`] order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndexedLayout {
    pub primitives: Vec<LayoutPrimitive>,
}

/// A vertex already written for a mesh corner: the next one for the same corner, and its
/// colour and quantised normal packed into one comparable key.
struct Written {
    next: u32,
    key: u64,
}

/// The sharing key of a face: its colour (24 bits) and quantised normal (3 x 13 bits).
fn face_key(colour: [u8; 4], n: [f32; 3]) -> u64 {
    // c * steps + 16384.5 is positive for a unit component, so truncation rounds to nearest.
    let q = |c: f32| u64::from((c * NORMAL_STEPS + 16_384.5) as u32 & 0x7fff);
    (u64::from(colour[0]) << 56)
        | (u64::from(colour[1]) << 48)
        | (u64::from(colour[2]) << 40)
        | (q(n[0]) << 30)
        | (q(n[1]) << 15)
        | q(n[2])
}

const NONE: u32 = u32::MAX;

impl IndexedLayout {
    /// Lays out `mesh` with `placed` positions (one per mesh vertex, in file axes).
    pub fn new(mesh: &Mesh, placed: &[[f64; 3]]) -> Self {
        let mut by_material: Vec<Vec<(u32, [f32; 3])>> = (0..Material::ALL.len())
            .map(|_| Vec::with_capacity(mesh.triangles.len()))
            .collect();
        for (t, (&tri, style)) in mesh.triangles.iter().zip(&mesh.styles).enumerate() {
            if let Some(n) = face_normal(tri.map(|i| placed[i as usize])) {
                by_material[style.material as usize].push((t as u32, n));
            }
        }
        // The first vertex written for each mesh corner in the current primitive.
        let mut first = vec![NONE; mesh.positions.len()];
        let mut primitives = Vec::new();
        for (material, triangles) in Material::ALL.into_iter().zip(by_material) {
            if triangles.is_empty() {
                continue;
            }
            // At most three vertices per triangle: reserving that never moves the buffers, and
            // pages never written are never touched.
            let most = triangles.len() * 3;
            let mut p = LayoutPrimitive {
                material: Some(material),
                positions: Vec::with_capacity(most),
                normals: Vec::with_capacity(most),
                colours: Vec::with_capacity(most),
                indices: Vec::with_capacity(most),
            };
            let mut written: Vec<Written> = Vec::with_capacity(most);
            let mut touched: Vec<u32> = Vec::with_capacity(most);
            for (t, normal) in triangles {
                let t = t as usize;
                let [r, g, b] = mesh.styles[t].colour.to_linear_u8();
                let colour = [r, g, b, 255];
                let key = face_key(colour, normal);
                for corner in mesh.triangles[t] {
                    let slot = &mut first[corner as usize];
                    let mut at = *slot;
                    let mut found = NONE;
                    while at != NONE {
                        let w = &written[at as usize];
                        if w.key == key {
                            found = at;
                            break;
                        }
                        at = w.next;
                    }
                    if found == NONE {
                        found = p.positions.len() as u32;
                        if *slot == NONE {
                            touched.push(corner);
                        }
                        written.push(Written { next: *slot, key });
                        *slot = found;
                        p.positions.push(placed[corner as usize].map(|c| c as f32));
                        p.normals.push(normal);
                        p.colours.push(colour);
                    }
                    p.indices.push(found);
                }
            }
            for corner in touched {
                first[corner as usize] = NONE;
            }
            primitives.push(p);
        }
        Self { primitives }
    }

    /// Vertices over all primitives.
    pub fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions.len()).sum()
    }

    /// Triangles over all primitives.
    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.indices.len() / 3).sum()
    }
}

/// The unit normal of a counter-clockwise triangle in file axes, or `None` when the triangle has
/// no area (in f64, or once its corners are rounded to f32).
fn face_normal([a, b, c]: [[f64; 3]; 3]) -> Option<[f32; 3]> {
    let n = triangle_normal(a, b, c);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if !len.is_finite() || len <= 1e-12 {
        return None;
    }
    // Also require the f32 positions to keep an area, so clients do not see a degenerate triangle.
    let f = |p: [f64; 3]| p.map(|x| x as f32);
    let (fa, fb, fc) = (f(a), f(b), f(c));
    if fa == fb || fb == fc || fa == fc {
        return None;
    }
    Some([
        (n[0] / len) as f32,
        (n[1] / len) as f32,
        (n[2] / len) as f32,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{FaceStyle, Rgb};

    fn style(material: Material, colour: Rgb) -> FaceStyle {
        FaceStyle { material, colour }
    }

    /// A unit square in the x/y plane split into two triangles, plus a third triangle folded up
    /// along one edge.
    fn quad_and_fold() -> Mesh {
        let mut m = Mesh::default();
        for p in [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5, 2.0, 1.0],
        ] {
            m.push_vertex(p);
        }
        let wall = style(Material::Wall, Rgb(200, 200, 200));
        m.push_triangle([0, 1, 2], wall);
        m.push_triangle([0, 2, 3], wall);
        m.push_triangle([3, 2, 4], wall);
        m
    }

    #[test]
    fn a_quad_is_four_vertices_and_a_fold_gets_its_own() {
        let m = quad_and_fold();
        let layout = IndexedLayout::new(&m, &m.positions);
        assert_eq!(layout.primitives.len(), 1);
        let p = &layout.primitives[0];
        // Quad: 4 shared vertices; the folded triangle: 3 of its own (another normal).
        assert_eq!(p.positions.len(), 7);
        assert_eq!(p.indices, [0, 1, 2, 0, 2, 3, 4, 5, 6]);
        assert_eq!(p.normals[0], [0.0, 0.0, 1.0]);
        assert_eq!(layout.triangle_count(), 3);
    }

    #[test]
    fn colours_and_materials_are_never_shared() {
        let mut m = quad_and_fold();
        m.styles[1].colour = Rgb(10, 20, 30);
        m.styles[2].material = Material::Roof;
        let layout = IndexedLayout::new(&m, &m.positions);
        let counts: Vec<_> = layout
            .primitives
            .iter()
            .map(|p| (p.material, p.positions.len(), p.indices.len()))
            .collect();
        assert_eq!(
            counts,
            [(Some(Material::Wall), 6, 6), (Some(Material::Roof), 3, 3)]
        );
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let mut m = quad_and_fold();
        m.push_triangle([0, 1, 1], style(Material::Wall, Rgb::GROUND));
        let layout = IndexedLayout::new(&m, &m.positions);
        assert_eq!(layout.triangle_count(), 3);
    }
}

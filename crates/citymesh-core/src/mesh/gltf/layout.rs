//! Stage 3 of the encoder: the indexed vertex layout.
//!
//! Faces are flat shaded. Where the file stores normals, every vertex carries its face's normal
//! and colour, and a vertex is shared by the triangles that meet at one stored position with the
//! same colour and the same normal (quantised to [`NORMAL_STEPS`] steps per unit, so rounding
//! noise between the triangles of one plane does not split them): a wall quad becomes 4 vertices
//! instead of 6, a flat roof of n triangles about n + 2. Where it stores none (the client computes
//! flat normals, as the glTF specification requires), a vertex is shared by every triangle of its
//! colour at that position. Triangles whose stored corners coincide, or that have no area, are
//! left out, since they have no normal.

use crate::mesh::{Material, Mesh, triangle_normal};

/// Normals are compared in steps of 1/16384 per component (about 0.0035 degrees): far below any
/// visible crease, far above the rounding noise between triangles of one plane.
const NORMAL_STEPS: f32 = 16_384.0;

/// One primitive: a material's vertices and triangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LayoutPrimitive {
    pub material: Option<Material>,
    /// Positions as stored (f32 metres in file axes, or quantization steps).
    pub positions: Vec<[f32; 3]>,
    /// Unit face normals in file axes; empty when the file stores none.
    pub normals: Vec<[f32; 3]>,
    /// Linear RGBA colours.
    pub colours: Vec<[u8; 4]>,
    /// The feature (building) of each vertex, [`crate::mesh::NO_FEATURE`] for none.
    pub features: Vec<u32>,
    /// Three per triangle, counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

/// The primitives of a mesh, one per material present, in [`Material::ALL`] order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndexedLayout {
    pub primitives: Vec<LayoutPrimitive>,
    /// Whether the vertices carry normals.
    pub has_normals: bool,
}

/// A vertex already written for a stored position: the next one for the same position, and its
/// colour, feature and quantised normal packed into one comparable key.
struct Written {
    next: u32,
    key: u128,
}

/// The sharing key of a face: its colour (24 bits), its feature (32 bits) and, where normals are
/// stored, its quantised normal (3 x 15 bits), each in bits of its own.
fn face_key(colour: [u8; 4], feature: u32, n: Option<[f32; 3]>) -> u128 {
    // c * steps + 16384.5 is positive for a unit component, so truncation rounds to nearest.
    let q = |c: f32| u128::from((c * NORMAL_STEPS + 16_384.5) as u32 & 0x7fff);
    let normal = n.map_or(0, |n| (q(n[0]) << 30) | (q(n[1]) << 15) | q(n[2]));
    (u128::from(colour[0]) << 112)
        | (u128::from(colour[1]) << 104)
        | (u128::from(colour[2]) << 96)
        | (u128::from(feature) << 64)
        | normal
}

const NONE: u32 = u32::MAX;

/// Vertices a weld looks back over: generators write a face's corners, and the faces that share
/// them, close together, and a table this small stays in the cache.
const WELD_WINDOW: usize = 4096;
/// Slots of a weld table (a power of two, twice the window).
const WELD_SLOTS: usize = 2 * WELD_WINDOW;
/// Probes before a vertex gives up looking (it then stands for itself): bounds the work on
/// positions that happen, or are made, to collide.
const WELD_PROBES: usize = 16;

/// Each mesh vertex's representative: an earlier vertex stored at the same position, if one is
/// within the last one to two [`WELD_WINDOW`]s, else itself. Faces that the generator gave
/// corners of their own so still share them in the file. Two open-addressing tables of vertex
/// indices, the current window's and the previous one's.
fn weld(stored: &[[f32; 3]]) -> Vec<u32> {
    let slot_of = |p: &[f32; 3]| {
        let [x, y, z] = p.map(|c| u64::from(c.to_bits()));
        let h = ((x << 32) | y).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ z.wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        (h >> 40) as usize
    };
    let find = |table: &[u32], p: &[f32; 3], start: usize| {
        for k in 0..WELD_PROBES {
            let slot = (start + k) & (WELD_SLOTS - 1);
            match table[slot] {
                NONE => return Err(Some(slot)),
                v if stored[v as usize] == *p => return Ok(v),
                _ => {}
            }
        }
        Err(None)
    };
    let mut current = vec![NONE; WELD_SLOTS];
    let mut previous = vec![NONE; WELD_SLOTS];
    let mut out = Vec::with_capacity(stored.len());
    for (i, p) in stored.iter().enumerate() {
        if i % WELD_WINDOW == 0 {
            std::mem::swap(&mut current, &mut previous);
            current.fill(NONE);
        }
        let start = slot_of(p);
        if let Ok(v) = find(&previous, p, start) {
            out.push(v);
            continue;
        }
        match find(&current, p, start) {
            Ok(v) => out.push(v),
            Err(free) => {
                if let Some(slot) = free {
                    current[slot] = i as u32;
                }
                out.push(i as u32);
            }
        }
    }
    out
}

impl IndexedLayout {
    /// Lays out `mesh` with its `stored` positions (as the file holds them; for sharing), one per
    /// mesh vertex, and normals from `normals_in` (the positions in file axes, metres) when the
    /// file stores normals.
    pub fn new(mesh: &Mesh, stored: &[[f32; 3]], normals_in: Option<&[[f64; 3]]>) -> Self {
        let with_normals = normals_in.is_some();
        let canonical = weld(stored);
        // Each triangle's welded corners and normal (none when it has no area), and how many
        // each material has.
        let mut counts = [0usize; Material::ALL.len()];
        let faces: Vec<Option<([u32; 3], [f32; 3])>> = mesh
            .triangles
            .iter()
            .zip(&mesh.styles)
            .map(|(&tri, style)| {
                let corners = tri.map(|i| canonical[i as usize]);
                let [a, b, c] = corners;
                let face = if a == b || b == c || a == c {
                    None
                } else if let Some(placed) = normals_in {
                    face_normal(tri.map(|i| placed[i as usize])).map(|n| (corners, n))
                } else {
                    // Areas do not change with the placement: test in the mesh's own frame.
                    has_area(tri.map(|i| mesh.positions[i as usize])).then_some((corners, [0.0; 3]))
                };
                counts[style.material as usize] += usize::from(face.is_some());
                face
            })
            .collect();
        // The triangles that have a face, grouped by material in mesh order (a counting sort),
        // so each primitive reads only its own.
        let mut starts = [0usize; Material::ALL.len() + 1];
        for (m, &count) in counts.iter().enumerate() {
            starts[m + 1] = starts[m] + count;
        }
        let mut order = vec![0u32; starts[Material::ALL.len()]];
        let mut next = starts;
        for (t, (style, face)) in mesh.styles.iter().zip(&faces).enumerate() {
            if face.is_some() {
                let m = style.material as usize;
                order[next[m]] = t as u32;
                next[m] += 1;
            }
        }
        // The first vertex written for each welded corner in the current primitive.
        let mut first = vec![NONE; mesh.positions.len()];
        let mut primitives = Vec::new();
        for (m, (material, count)) in Material::ALL.into_iter().zip(counts).enumerate() {
            if count == 0 {
                continue;
            }
            let triangles = order[starts[m]..starts[m + 1]].iter().filter_map(|&t| {
                let t = t as usize;
                faces[t].map(|f| (&mesh.styles[t], f))
            });
            // At most three vertices per triangle: reserving that never moves the buffers.
            let most = count * 3;
            let mut p = LayoutPrimitive {
                material: Some(material),
                positions: Vec::with_capacity(most),
                normals: Vec::with_capacity(if with_normals { most } else { 0 }),
                colours: Vec::with_capacity(most),
                features: Vec::with_capacity(most),
                indices: Vec::with_capacity(most),
            };
            let mut written: Vec<Written> = Vec::with_capacity(most);
            let mut touched: Vec<u32> = Vec::with_capacity(most);
            for (style, (corners, normal)) in triangles {
                let [r, g, b] = style.colour.to_linear_u8();
                let colour = [r, g, b, 255];
                let key = face_key(colour, style.feature, with_normals.then_some(normal));
                for corner in corners {
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
                        p.positions.push(stored[corner as usize]);
                        if with_normals {
                            p.normals.push(normal);
                        }
                        p.colours.push(colour);
                        p.features.push(style.feature);
                    }
                    p.indices.push(found);
                }
            }
            for corner in touched {
                first[corner as usize] = NONE;
            }
            primitives.push(p);
        }
        Self {
            primitives,
            has_normals: with_normals,
        }
    }

    /// Vertices over all primitives.
    pub fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions.len()).sum()
    }

    /// Whether any vertex belongs to a feature.
    pub fn has_features(&self) -> bool {
        self.primitives
            .iter()
            .any(|p| p.features.iter().any(|&f| f != crate::mesh::NO_FEATURE))
    }

    /// Triangles over all primitives.
    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.indices.len() / 3).sum()
    }
}

/// Whether a triangle has an area (the test [`face_normal`] makes, without the normal).
fn has_area([a, b, c]: [[f64; 3]; 3]) -> bool {
    let n = triangle_normal(a, b, c);
    let squared = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    squared.is_finite() && squared > 1e-24
}

/// The unit normal of a counter-clockwise triangle in file axes, or `None` when the triangle has
/// no area.
fn face_normal([a, b, c]: [[f64; 3]; 3]) -> Option<[f32; 3]> {
    let n = triangle_normal(a, b, c);
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if !len.is_finite() || len <= 1e-12 {
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

    fn layout_of(m: &Mesh, normals: bool) -> IndexedLayout {
        let stored: Vec<[f32; 3]> = m.positions.iter().map(|p| p.map(|c| c as f32)).collect();
        IndexedLayout::new(m, &stored, normals.then_some(&m.positions[..]))
    }

    fn style(material: Material, colour: Rgb) -> FaceStyle {
        FaceStyle::plain(material, colour)
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
        let layout = layout_of(&m, true);
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
        let layout = layout_of(&m, true);
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
    fn without_normals_a_corner_is_shared_by_every_face_of_its_colour() {
        let mut m = quad_and_fold();
        // The fold gets corners of its own at the same places: welded all the same.
        let (a, b) = (
            m.push_vertex([0.0, 1.0, 0.0]),
            m.push_vertex([1.0, 1.0, 0.0]),
        );
        let c = m.push_vertex([0.5, 2.0, 1.0]);
        m.triangles[2] = [a, b, c];
        let layout = layout_of(&m, false);
        let p = &layout.primitives[0];
        assert_eq!(p.positions.len(), 5);
        assert_eq!(p.indices, [0, 1, 2, 0, 2, 3, 3, 2, 4]);
        assert!(p.normals.is_empty());
        // With normals, the fold keeps vertices of its own.
        assert_eq!(layout_of(&m, true).primitives[0].positions.len(), 7);
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let mut m = quad_and_fold();
        m.push_triangle([0, 1, 1], style(Material::Wall, Rgb::GROUND));
        let layout = layout_of(&m, true);
        assert_eq!(layout.triangle_count(), 3);
    }
}

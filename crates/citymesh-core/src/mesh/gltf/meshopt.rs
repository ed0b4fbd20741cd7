//! meshoptimizer for the `meshopt` encoding: the order of a primitive's triangles and vertices
//! that compresses best, and the compression of one buffer view (`EXT_meshopt_compression`).

use super::layout::LayoutPrimitive;

/// How a view is compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewMode {
    /// Vertex attributes (the byte stride a multiple of 4).
    Attributes,
    /// Triangle indices (2 or 4 bytes each, a multiple of 3 of them).
    Triangles,
}

impl ViewMode {
    /// The name in `EXT_meshopt_compression`.
    pub fn name(self) -> &'static str {
        match self {
            ViewMode::Attributes => "ATTRIBUTES",
            ViewMode::Triangles => "TRIANGLES",
        }
    }
}

/// Reorders a primitive's triangles for the vertex cache and its vertices by first use, which
/// is what meshoptimizer's codecs compress best. The triangles and their corners stay the same.
pub fn reorder(p: &mut LayoutPrimitive) {
    let n = p.positions.len();
    if n == 0 {
        return;
    }
    let indices = meshopt::optimize_vertex_cache(&p.indices, n);
    // remap[old] = new; every vertex of a layout is used, so every entry is set.
    let remap = meshopt::optimize_vertex_fetch_remap(&indices, n);
    p.indices = indices.iter().map(|&i| remap[i as usize]).collect();
    permute(&mut p.positions, &remap);
    permute(&mut p.normals, &remap);
    permute(&mut p.colours, &remap);
    permute(&mut p.features, &remap);
}

/// Moves each element to its new place (`remap[old] = new`).
fn permute<T: Copy>(values: &mut Vec<T>, remap: &[u32]) {
    let Some(&fill) = values.first() else {
        return;
    };
    let mut moved = vec![fill; values.len()];
    for (old, &new) in remap.iter().enumerate() {
        if let (Some(slot), Some(&v)) = (moved.get_mut(new as usize), values.get(old)) {
            *slot = v;
        }
    }
    *values = moved;
}

/// `data` (elements of `element` bytes) compressed by mode; vertex codec version 0, the one
/// `EXT_meshopt_compression` defines.
pub fn compress_view(data: &[u8], element: usize, mode: ViewMode) -> Vec<u8> {
    match mode {
        ViewMode::Triangles => {
            let indices: Vec<u32> = if element == 2 {
                data.chunks_exact(2)
                    .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
                    .collect()
            } else {
                data.chunks_exact(4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            };
            let vertices = indices.iter().max().map_or(0, |&m| m as usize + 1);
            meshopt::encode_index_buffer(&indices, vertices).unwrap_or_default()
        }
        ViewMode::Attributes => match element {
            4 => encode::<4>(data),
            8 => encode::<8>(data),
            12 => encode::<12>(data),
            16 => encode::<16>(data),
            _ => Vec::new(),
        },
    }
}

fn encode<const N: usize>(data: &[u8]) -> Vec<u8> {
    let elements: Vec<[u8; N]> = data
        .chunks_exact(N)
        .map(|c| {
            let mut e = [0u8; N];
            e.copy_from_slice(c);
            e
        })
        .collect();
    meshopt::encode_vertex_buffer_level(&elements, 2, Some(0)).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compressed_views_decode_to_the_same_bytes() {
        let data: Vec<u8> = (0..64u32)
            .flat_map(|i| [i as u8, 0, (i * 3) as u8, 7, 1, 2, 3, 4])
            .collect();
        let packed = compress_view(&data, 8, ViewMode::Attributes);
        let back: Vec<[u8; 8]> = meshopt::decode_vertex_buffer(&packed, 64).unwrap();
        assert_eq!(back.concat(), data);
        // Version 0 of the vertex codec: the header byte is 0xa0.
        assert_eq!(packed[0], 0xa0);

        let indices: Vec<u8> = [0u16, 1, 2, 2, 1, 3, 3, 1, 4]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let packed = compress_view(&indices, 2, ViewMode::Triangles);
        let back: Vec<u16> = meshopt::decode_index_buffer(&packed, 9).unwrap();
        assert_eq!(back, [0, 1, 2, 2, 1, 3, 3, 1, 4]);
    }

    #[test]
    fn reordering_keeps_every_triangle() {
        let mut p = LayoutPrimitive {
            material: None,
            positions: (0..5).map(|i| [i as f32, 0.0, 0.0]).collect(),
            normals: Vec::new(),
            colours: (0..5).map(|i| [i as u8, 0, 0, 255]).collect(),
            features: Vec::new(),
            indices: vec![4, 3, 2, 0, 1, 2, 2, 1, 3],
        };
        let before = triangles(&p);
        reorder(&mut p);
        assert_eq!(triangles(&p), before);
    }

    /// The triangles by their corners' positions, each turned to start at its smallest corner,
    /// sorted.
    fn triangles(p: &LayoutPrimitive) -> Vec<[u32; 3]> {
        let mut t: Vec<[u32; 3]> = p
            .indices
            .chunks_exact(3)
            .map(|c| {
                let x = [0, 1, 2].map(|k| p.positions[c[k] as usize][0] as u32);
                let m = (0..3).min_by_key(|&k| x[k]).unwrap_or(0);
                [x[m], x[(m + 1) % 3], x[(m + 2) % 3]]
            })
            .collect();
        t.sort_unstable();
        t
    }
}

//! GLB (binary glTF 2.0) encoding of a [`Mesh`].
//!
//! glTF is Y-up: (east, north, up) becomes (x, y, z) = (east, up, -north) (METHOD.md section 8), a
//! proper rotation, so counter-clockwise triangles stay counter-clockwise. Faces are flat shaded: each
//! triangle gets its own three vertices with the face normal and the face colour (`COLOR_0`, linear).
//! There is one primitive per [`Material`]. Positions are f32 relative to the scene origin, which
//! the file records in `scenes[0].extras.origin` so a client can place it.

use super::{Material, Mesh};
use serde_json::{Value, json};

/// Where a GLB's local frame sits on the Earth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GlbOrigin {
    pub lon: f64,
    pub lat: f64,
    /// Metres above mean sea level (the EGM96 geoid, like SRTM heights).
    pub height: f64,
}

const ARRAY_BUFFER: u32 = 34962;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;

/// How mesh positions (local east, north, up metres) are placed in the file.
#[derive(Debug, Clone, Copy)]
pub enum Placement {
    /// glTF y-up axes around the frame's origin: (x, y, z) = (east, up, -north); the origin is
    /// recorded in `scenes[0].extras.origin`.
    Local(GlbOrigin),
    /// 3D Tiles content: Earth-centred coordinates relative to `centre` (ECEF metres), z-up,
    /// under a node whose matrix turns them y-up and moves them to `centre`, so a 3D Tiles
    /// client's standard y-up to z-up transform gives ECEF.
    Ecef {
        frame: crate::geo::LocalFrame,
        centre: [f64; 3],
    },
}

/// Encodes the mesh as GLB bytes in local glTF axes. Degenerate triangles (no area, so no normal)
/// are left out. `buildings` (OSM ids such as `way/123`) are listed in
/// `scenes[0].extras.buildings`.
pub fn write_glb(mesh: &Mesh, origin: GlbOrigin, buildings: &[String]) -> Vec<u8> {
    write_glb_placed(mesh, Placement::Local(origin), buildings)
}

/// Encodes the mesh as GLB bytes with the given placement.
pub fn write_glb_placed(mesh: &Mesh, placement: Placement, buildings: &[String]) -> Vec<u8> {
    let map = |p: [f64; 3]| -> [f64; 3] {
        match &placement {
            Placement::Local(_) => [p[0], p[2], -p[1]],
            Placement::Ecef { frame, centre } => {
                let (lon, lat, h) = frame.to_geographic(p);
                let e = crate::geo::geodetic_to_ecef(lon, lat, h);
                [e[0] - centre[0], e[1] - centre[1], e[2] - centre[2]]
            }
        }
    };
    // Positions in file axes, and the triangles with a usable normal, bucketed by material.
    let placed: Vec<[f64; 3]> = mesh.positions.iter().map(|&p| map(p)).collect();
    let mut buckets: Vec<Vec<(usize, [f32; 3])>> = vec![Vec::new(); Material::ALL.len()];
    for (t, (&tri, style)) in mesh.triangles.iter().zip(&mesh.styles).enumerate() {
        if let Some(n) = face_normal(tri.map(|i| placed[i as usize])) {
            buckets[style.material as usize].push((t, n));
        }
    }
    let vertex_count: usize = buckets.iter().map(|b| b.len() * 3).sum();

    let pos_len = vertex_count * 12;
    let col_len = vertex_count * 4;
    let mut bin = vec![0u8; pos_len * 2 + col_len];
    let (pos_bytes, rest) = bin.split_at_mut(pos_len);
    let (nor_bytes, col_bytes) = rest.split_at_mut(pos_len);

    let mut materials = Vec::new();
    let mut primitives = Vec::new();
    let mut accessors = Vec::new();
    let mut v = 0usize;
    for (material, bucket) in Material::ALL.iter().zip(&buckets) {
        if bucket.is_empty() {
            continue;
        }
        let first = v;
        let mut min = [f32::INFINITY; 3];
        let mut max = [f32::NEG_INFINITY; 3];
        for &(t, n) in bucket {
            let tri = mesh.triangles[t];
            let [r, g, b] = mesh.styles[t].colour.to_linear_u8();
            for i in tri {
                let p = placed[i as usize].map(|c| c as f32);
                for k in 0..3 {
                    min[k] = min[k].min(p[k]);
                    max[k] = max[k].max(p[k]);
                    pos_bytes[v * 12 + k * 4..v * 12 + k * 4 + 4]
                        .copy_from_slice(&p[k].to_le_bytes());
                    nor_bytes[v * 12 + k * 4..v * 12 + k * 4 + 4]
                        .copy_from_slice(&n[k].to_le_bytes());
                }
                col_bytes[v * 4..v * 4 + 4].copy_from_slice(&[r, g, b, 255]);
                v += 1;
            }
        }
        let count = v - first;
        let a = accessors.len();
        accessors.push(
            json!({"bufferView": 0, "byteOffset": first * 12, "componentType": FLOAT,
            "count": count, "type": "VEC3", "min": min, "max": max}),
        );
        accessors.push(
            json!({"bufferView": 1, "byteOffset": first * 12, "componentType": FLOAT,
            "count": count, "type": "VEC3"}),
        );
        accessors.push(
            json!({"bufferView": 2, "byteOffset": first * 4, "componentType": UNSIGNED_BYTE,
            "normalized": true, "count": count, "type": "VEC4"}),
        );
        primitives.push(
            json!({"attributes": {"POSITION": a, "NORMAL": a + 1, "COLOR_0": a + 2},
            "material": materials.len(), "mode": 4}),
        );
        materials.push(json!({"name": material.name(), "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}}));
    }

    let (extras, node) = match &placement {
        Placement::Local(origin) => (
            json!({"origin": {"lon": origin.lon, "lat": origin.lat, "height": origin.height},
                "heightReference": "metres above mean sea level (EGM96 geoid, as SRTM)",
                "axes": "x = east, y = up, z = -north, metres from the origin (local frame on WGS84)",
                "buildings": buildings}),
            json!({"name": "citymesh", "mesh": 0}),
        ),
        Placement::Ecef { centre: c, .. } => (
            json!({"axes": "ECEF (WGS84) metres relative to the node translation, z-up; heights above the ellipsoid are SRTM heights",
                "buildings": buildings}),
            // z-up to y-up, then the translation (y-up too), column-major.
            json!({"name": "citymesh", "mesh": 0, "matrix": [
                1.0, 0.0, 0.0, 0.0,
                0.0, 0.0, -1.0, 0.0,
                0.0, 1.0, 0.0, 0.0,
                c[0], c[2], -c[1], 1.0]}),
        ),
    };
    let generator = concat!("citymesh ", env!("CARGO_PKG_VERSION"));
    let document = if vertex_count == 0 {
        json!({"asset": {"version": "2.0", "generator": generator},
            "scene": 0, "scenes": [{"name": "citymesh", "extras": extras}]})
    } else {
        json!({
            "asset": {"version": "2.0", "generator": generator},
            "scene": 0,
            "scenes": [{"name": "citymesh", "nodes": [0], "extras": extras}],
            "nodes": [node],
            "meshes": [{"name": "citymesh", "primitives": primitives}],
            "materials": materials,
            "accessors": accessors,
            "bufferViews": [
                // One view per attribute, shared by the primitives' accessors: so a stride.
                {"buffer": 0, "byteOffset": 0, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER},
                {"buffer": 0, "byteOffset": pos_len, "byteLength": pos_len, "byteStride": 12, "target": ARRAY_BUFFER},
                {"buffer": 0, "byteOffset": pos_len * 2, "byteLength": col_len, "byteStride": 4, "target": ARRAY_BUFFER},
            ],
            "buffers": [{"byteLength": bin.len()}],
        })
    };
    encode_glb(&document, bin)
}

/// The unit normal of a counter-clockwise triangle in file axes, or `None` when the triangle has
/// no area (in f64, or once its corners are rounded to f32).
fn face_normal([a, b, c]: [[f64; 3]; 3]) -> Option<[f32; 3]> {
    let n = super::triangle_normal(a, b, c);
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

/// Wraps a JSON document and a binary buffer into the GLB container.
fn encode_glb(document: &Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut json = serde_json::to_vec(document).expect("a serde_json Value always serialises");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let has_bin = !bin.is_empty();
    let total = 12 + 8 + json.len() + if has_bin { 8 + bin.len() } else { 0 };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if has_bin {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}

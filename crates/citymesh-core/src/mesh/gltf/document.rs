//! Stage 4 of the encoder: the glTF JSON document and its binary buffer, in the chosen
//! [`Encoding`].
//!
//! The buffer holds, in order: all positions, all normals (where stored), all colours
//! (normalised u8 VEC4), each a view shared by the primitives' accessors (hence a byte stride),
//! then each primitive's indices (u16 when its vertices fit, else u32) in a view of its own.
//! Plain files store f32 positions and normals; quantized ones u16 positions (padded to 8 bytes)
//! and normalised i8 normals (padded to 4) under `KHR_mesh_quantization`, the node's matrix
//! mapping steps back to metres. Meshopt files compress each view with meshoptimizer's codecs
//! (`EXT_meshopt_compression`, required): the GLB's buffer holds the compressed views, and a
//! second buffer without data marks where the decoded views go.

use super::encoding::Encoding;
use super::layout::IndexedLayout;
use super::meshopt::{ViewMode, compress_view};
use super::metadata::{NULL_FEATURE_ID, PropertyTable};
use super::placement::NodePlacement;
use super::quantize::Quantization;
use serde_json::{Map, Value, json};

const GENERATOR: &str = concat!("citymesh ", env!("CARGO_PKG_VERSION"));

const ARRAY_BUFFER: u32 = 34_962;
const ELEMENT_ARRAY_BUFFER: u32 = 34_963;
const BYTE: u32 = 5_120;
const UNSIGNED_BYTE: u32 = 5_121;
const UNSIGNED_SHORT: u32 = 5_123;
const UNSIGNED_INT: u32 = 5_125;
const FLOAT: u32 = 5_126;

/// A JSON document and the binary buffer it describes.
pub struct Document {
    pub json: Vec<u8>,
    pub bin: Vec<u8>,
}

/// One buffer view before compression.
struct View {
    offset: usize,
    length: usize,
    /// Bytes per element: the byte stride of an attribute view, the index size of an index view.
    element: usize,
    target: u32,
}

impl View {
    fn mode(&self) -> ViewMode {
        if self.target == ELEMENT_ARRAY_BUFFER {
            ViewMode::Triangles
        } else {
            ViewMode::Attributes
        }
    }
}

/// Sizes of the stored attributes in an encoding.
struct AttributeSizes {
    position: usize,
    normal: usize,
}

fn sizes(encoding: Encoding) -> AttributeSizes {
    if encoding.is_quantized() {
        AttributeSizes {
            position: 8,
            normal: 4,
        }
    } else {
        AttributeSizes {
            position: 12,
            normal: 12,
        }
    }
}

/// Writes the document of `layout` in `encoding`. `quantization` must be given for the quantized
/// encodings (the positions in `layout` are then step counts). With `features`, the vertices'
/// features become `_FEATURE_ID_0` (`EXT_mesh_features`) pointing at its rows
/// (`EXT_structural_metadata`).
pub fn assemble(
    layout: &IndexedLayout,
    node: &NodePlacement,
    quantization: Option<Quantization>,
    encoding: Encoding,
    buildings: &[String],
    features: Option<&PropertyTable>,
) -> Document {
    let mut root = Map::new();
    root.insert(
        "asset".into(),
        json!({"generator": GENERATOR, "version": "2.0"}),
    );
    let extras = scene_extras(node, buildings);
    let vertices = layout.vertex_count();
    if vertices == 0 {
        root.insert("scene".into(), json!(0));
        root.insert("scenes".into(), scenes(None, extras));
        return Document {
            json: serde_json::to_vec(&Value::Object(root)).unwrap_or_default(),
            bin: Vec::new(),
        };
    }
    let size = sizes(encoding);
    let features = features.filter(|t| t.count() > 0 && layout.has_features());
    let (bin, views, feature_view) = write_binary(layout, encoding, &size, features.is_some());

    let mut accessors = Vec::new();
    let mut materials = Vec::new();
    let mut primitives = Vec::new();
    // Views 0.. are positions, normals (if any), colours, feature ids (if any), then one per
    // primitive's indices.
    let normals_view = layout.has_normals.then_some(1);
    let colours_view = if layout.has_normals { 2 } else { 1 };
    let first_index_view = colours_view + 1 + usize::from(feature_view.is_some());
    let mut first = 0usize;
    for (k, p) in layout.primitives.iter().enumerate() {
        let count = p.positions.len();
        let (min, max) = bounds(&p.positions);
        let mut attributes = Map::new();
        attributes.insert("POSITION".into(), json!(accessors.len()));
        accessors.push(json!({
            "bufferView": 0,
            "byteOffset": first * size.position,
            "componentType": if encoding.is_quantized() { UNSIGNED_SHORT } else { FLOAT },
            "count": count,
            "type": "VEC3",
            "min": min,
            "max": max,
        }));
        if let Some(view) = normals_view {
            attributes.insert("NORMAL".into(), json!(accessors.len()));
            let mut a = json!({
                "bufferView": view,
                "byteOffset": first * size.normal,
                "componentType": if encoding.is_quantized() { BYTE } else { FLOAT },
                "count": count,
                "type": "VEC3",
            });
            if encoding.is_quantized() {
                a["normalized"] = json!(true);
            }
            accessors.push(a);
        }
        attributes.insert("COLOR_0".into(), json!(accessors.len()));
        accessors.push(json!({
            "bufferView": colours_view,
            "byteOffset": first * 4,
            "componentType": UNSIGNED_BYTE,
            "normalized": true,
            "count": count,
            "type": "VEC4",
        }));
        let mut extensions = None;
        if let Some((view, from)) = feature_view.filter(|&(_, from)| first >= from) {
            attributes.insert("_FEATURE_ID_0".into(), json!(accessors.len()));
            accessors.push(json!({
                "bufferView": view,
                "byteOffset": (first - from) * 4,
                "componentType": FLOAT,
                "count": count,
                "type": "SCALAR",
            }));
            let mut ids = json!({"featureCount": features.map_or(0, PropertyTable::count),
                "attribute": 0, "propertyTable": 0});
            if p.features.contains(&crate::mesh::NO_FEATURE) {
                ids["nullFeatureId"] = json!(NULL_FEATURE_ID);
            }
            extensions = Some(json!({"EXT_mesh_features": {"featureIds": [ids]}}));
        }
        let index_view = first_index_view + k;
        let indices = accessors.len();
        accessors.push(json!({
            "bufferView": index_view,
            "componentType": if views[index_view].element == 2 { UNSIGNED_SHORT } else { UNSIGNED_INT },
            "count": p.indices.len(),
            "type": "SCALAR",
        }));
        let name = p.material.map_or("mesh", |m| m.name());
        materials.push(json!({
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9,
            },
        }));
        let mut primitive = json!({
            "attributes": attributes,
            "indices": indices,
            "material": k,
            "mode": 4,
        });
        if let Some(e) = extensions {
            primitive["extensions"] = e;
        }
        primitives.push(primitive);
        first += count;
    }

    let (mut bin, mut buffers, mut view_json) = if encoding == Encoding::Meshopt {
        compressed(&bin, &views)
    } else {
        let views = views
            .iter()
            .map(|v| view_json(0, v.offset, v.length, v))
            .collect::<Vec<_>>();
        let buffers = json!([{"byteLength": bin.len()}]);
        (bin, buffers, views)
    };
    let metadata = features.map(|table| {
        let ext = table.append_to(&mut bin, &mut view_json);
        buffers[0]["byteLength"] = json!(bin.len());
        ext
    });

    let mut node_json = json!({"mesh": 0, "name": "citymesh"});
    if let Some(matrix) = node_matrix(node, quantization) {
        node_json["matrix"] = json!(matrix);
    }
    let required = encoding.extensions();
    let mut used: Vec<&str> = required.to_vec();
    if let Some(ext) = metadata {
        used.extend(["EXT_mesh_features", "EXT_structural_metadata"]);
        root.insert("extensions".into(), json!({"EXT_structural_metadata": ext}));
    }
    if !used.is_empty() {
        root.insert("extensionsUsed".into(), json!(used));
    }
    if !required.is_empty() {
        root.insert("extensionsRequired".into(), json!(required));
    }
    root.insert("accessors".into(), Value::Array(accessors));
    root.insert("bufferViews".into(), Value::Array(view_json));
    root.insert("buffers".into(), buffers);
    root.insert("materials".into(), Value::Array(materials));
    root.insert(
        "meshes".into(),
        json!([{"name": "citymesh", "primitives": primitives}]),
    );
    root.insert("nodes".into(), json!([node_json]));
    root.insert("scene".into(), json!(0));
    root.insert("scenes".into(), scenes(Some(0), extras));
    Document {
        json: serde_json::to_vec(&Value::Object(root)).unwrap_or_default(),
        bin,
    }
}

fn view_json(buffer: usize, offset: usize, length: usize, v: &View) -> Value {
    let mut view = json!({
        "buffer": buffer,
        "byteOffset": offset,
        "byteLength": length,
        "target": v.target,
    });
    if v.target == ARRAY_BUFFER {
        view["byteStride"] = json!(v.element);
    }
    view
}

/// The meshopt form: every view compressed into buffer 0; the views point into buffer 1, which
/// has no data of its own (the decoder fills it).
fn compressed(bin: &[u8], views: &[View]) -> (Vec<u8>, Value, Vec<Value>) {
    let mut out = Vec::with_capacity(bin.len() / 3);
    let mut json_views = Vec::with_capacity(views.len());
    for v in views {
        let data = &bin[v.offset..v.offset + v.length];
        let packed = compress_view(data, v.element, v.mode());
        let at = out.len();
        out.extend_from_slice(&packed);
        while !out.len().is_multiple_of(4) {
            out.push(0);
        }
        let mut view = view_json(1, v.offset, v.length, v);
        view["extensions"] = json!({"EXT_meshopt_compression": {
            "buffer": 0,
            "byteOffset": at,
            "byteLength": packed.len(),
            "byteStride": v.element,
            "count": v.length / v.element,
            "mode": v.mode().name(),
        }});
        json_views.push(view);
    }
    let buffers = json!([
        {"byteLength": out.len()},
        {"byteLength": bin.len(), "extensions": {"EXT_meshopt_compression": {"fallback": true}}},
    ]);
    (out, buffers, json_views)
}

/// The uncompressed buffer and its views: positions, normals (if any), colours, feature ids (if
/// `with_features`), then each primitive's indices, each view starting at a multiple of 4 bytes.
/// The feature id view covers the vertices from the first primitive with features on (the
/// ground, first, has none); it is returned with that first vertex.
fn write_binary(
    layout: &IndexedLayout,
    encoding: Encoding,
    size: &AttributeSizes,
    with_features: bool,
) -> (Vec<u8>, Vec<View>, Option<(usize, usize)>) {
    let vertices = layout.vertex_count();
    let mut views = Vec::with_capacity(3 + layout.primitives.len());
    let mut offset = 0;
    let mut add = |length: usize, element: usize, target: u32| {
        views.push(View {
            offset,
            length,
            element,
            target,
        });
        offset += length.next_multiple_of(4);
    };
    add(vertices * size.position, size.position, ARRAY_BUFFER);
    if layout.has_normals {
        add(vertices * size.normal, size.normal, ARRAY_BUFFER);
    }
    add(vertices * 4, 4, ARRAY_BUFFER);
    let feature_from = with_features.then(|| {
        layout
            .primitives
            .iter()
            .take_while(|p| p.features.iter().all(|&f| f == crate::mesh::NO_FEATURE))
            .map(|p| p.positions.len())
            .sum::<usize>()
    });
    if let Some(from) = feature_from {
        add((vertices - from) * 4, 4, ARRAY_BUFFER);
    }
    for p in &layout.primitives {
        let element = index_size(p.positions.len());
        add(p.indices.len() * element, element, ELEMENT_ARRAY_BUFFER);
    }
    let mut bin = vec![0u8; offset];
    let quantized = encoding.is_quantized();
    // Positions.
    {
        let v = &views[0];
        let mut dst = bin[v.offset..v.offset + v.length].chunks_exact_mut(size.position);
        for p in layout.primitives.iter().flat_map(|p| &p.positions) {
            let Some(d) = dst.next() else { break };
            if quantized {
                for k in 0..3 {
                    // Whole step counts within 0..=65535: exact.
                    d[2 * k..2 * k + 2].copy_from_slice(&(p[k] as u16).to_le_bytes());
                }
            } else {
                for k in 0..3 {
                    d[4 * k..4 * k + 4].copy_from_slice(&p[k].to_le_bytes());
                }
            }
        }
    }
    let mut next = 1;
    if layout.has_normals {
        let v = &views[next];
        let mut dst = bin[v.offset..v.offset + v.length].chunks_exact_mut(size.normal);
        for n in layout.primitives.iter().flat_map(|p| &p.normals) {
            let Some(d) = dst.next() else { break };
            if quantized {
                for k in 0..3 {
                    d[k] = ((n[k] * 127.0).round().clamp(-127.0, 127.0) as i8).to_le_bytes()[0];
                }
            } else {
                for k in 0..3 {
                    d[4 * k..4 * k + 4].copy_from_slice(&n[k].to_le_bytes());
                }
            }
        }
        next += 1;
    }
    {
        let v = &views[next];
        for (d, c) in bin[v.offset..v.offset + v.length]
            .chunks_exact_mut(4)
            .zip(layout.primitives.iter().flat_map(|p| &p.colours))
        {
            d.copy_from_slice(c);
        }
        next += 1;
    }
    let feature_view = feature_from.map(|from| {
        let v = &views[next];
        let ids = layout
            .primitives
            .iter()
            .flat_map(|p| &p.features)
            .skip(from);
        for (d, &f) in bin[v.offset..v.offset + v.length]
            .chunks_exact_mut(4)
            .zip(ids)
        {
            let id = if f == crate::mesh::NO_FEATURE {
                NULL_FEATURE_ID
            } else {
                f.min(NULL_FEATURE_ID - 1)
            };
            // Whole numbers below 2^24: exact in f32.
            d.copy_from_slice(&(id as f32).to_le_bytes());
        }
        next += 1;
        (next - 1, from)
    });
    for (p, v) in layout.primitives.iter().zip(&views[next..]) {
        let dst = &mut bin[v.offset..v.offset + v.length];
        if v.element == 2 {
            for (d, &i) in dst.chunks_exact_mut(2).zip(&p.indices) {
                // The primitive's vertices fit u16 here, so the cast is exact.
                d.copy_from_slice(&(i as u16).to_le_bytes());
            }
        } else {
            for (d, &i) in dst.chunks_exact_mut(4).zip(&p.indices) {
                d.copy_from_slice(&i.to_le_bytes());
            }
        }
    }
    (bin, views, feature_view)
}

/// 2-byte indices when a primitive's vertices fit (65,535 itself is reserved), else 4.
fn index_size(vertices: usize) -> usize {
    if vertices <= usize::from(u16::MAX) {
        2
    } else {
        4
    }
}

/// The node's column-major matrix: ECEF content turns z-up to y-up and moves to the centre;
/// quantized content first maps steps to metres. `None` when it is the identity.
fn node_matrix(node: &NodePlacement, q: Option<Quantization>) -> Option<[f64; 16]> {
    let (s, o) = q.map_or((1.0, [0.0; 3]), |q| (q.step, q.offset));
    match *node {
        NodePlacement::Origin { .. } => q.map(|_| {
            [
                s, 0.0, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, 0.0, s, 0.0, o[0], o[1], o[2], 1.0,
            ]
        }),
        NodePlacement::EcefCentre(c) => Some([
            s,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            -s,
            0.0,
            0.0,
            s,
            0.0,
            0.0,
            o[0] + c[0],
            o[2] + c[2],
            -o[1] - c[1],
            1.0,
        ]),
    }
}

/// The one scene, with its node (if any) and `extras` (moved in: `json!` would copy the id list).
fn scenes(node: Option<usize>, extras: Value) -> Value {
    let mut scene = Map::new();
    scene.insert("name".into(), json!("citymesh"));
    if let Some(node) = node {
        scene.insert("nodes".into(), json!([node]));
    }
    scene.insert("extras".into(), extras);
    Value::Array(vec![Value::Object(scene)])
}

/// Where the content sits and which buildings it holds, for clients.
fn scene_extras(node: &NodePlacement, buildings: &[String]) -> Value {
    match *node {
        NodePlacement::Origin { lon, lat, height } => json!({
            "origin": {"lon": lon, "lat": lat, "height": height},
            "heightReference": "metres above mean sea level (EGM96 geoid, as SRTM)",
            "axes": "x = east, y = up, z = -north, metres from the origin (local frame on WGS84)",
            "buildings": buildings}),
        NodePlacement::EcefCentre(_) => json!({
            "axes": "ECEF (WGS84) metres relative to the node translation, z-up; heights above the ellipsoid are SRTM heights",
            "buildings": buildings}),
    }
}

/// Per-component minimum and maximum of positions.
fn bounds(positions: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in positions {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    (min, max)
}

//! Stage 3 of the encoder: the glTF JSON document (built with `gltf-json`) and its binary
//! buffer.
//!
//! The buffer holds, in order: all positions (f32 VEC3), all normals (f32 VEC3), all colours
//! (normalised u8 VEC4), each a view shared by the primitives' accessors (hence a byte stride),
//! then each primitive's indices (u16 when its vertices fit, else u32) in a view of its own. The
//! JSON is assembled from the sizes alone, so the buffer can be written straight into the GLB.

use super::layout::{IndexedLayout, LayoutPrimitive};
use super::placement::{NodePlacement, Placed};
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use json::{Index, accessor, buffer, material, mesh};
use serde_json::{Value, json as value};
use std::collections::BTreeMap;

const GENERATOR: &str = concat!("citymesh ", env!("CARGO_PKG_VERSION"));

/// The JSON document of a layout; its binary buffer is [`write_binary`]'s output.
pub fn assemble(layout: &IndexedLayout, placed: &Placed, buildings: &[String]) -> Vec<u8> {
    let mut root = json::Root {
        asset: json::Asset {
            copyright: None,
            extensions: None,
            extras: None,
            generator: Some(GENERATOR.to_owned()),
            min_version: None,
            version: "2.0".to_owned(),
        },
        ..json::Root::default()
    };
    let extras = scene_extras(&placed.node, buildings);
    let vertices = layout.vertex_count();
    if vertices == 0 {
        root.scenes.push(scene(Vec::new(), extras));
        root.scene = Some(Index::new(0));
        return to_json(&root, &placed.node);
    }

    let pos_len = vertices * 12;
    let col_len = vertices * 4;
    let positions = root.push(view(0, pos_len, Some(12), buffer::Target::ArrayBuffer));
    let normals = root.push(view(
        pos_len,
        pos_len,
        Some(12),
        buffer::Target::ArrayBuffer,
    ));
    let colours = root.push(view(
        pos_len * 2,
        col_len,
        Some(4),
        buffer::Target::ArrayBuffer,
    ));
    let mut index_offset = pos_len * 2 + col_len;

    let mut primitives = Vec::with_capacity(layout.primitives.len());
    let mut first = 0usize;
    for p in &layout.primitives {
        let count = p.positions.len();
        let (min, max) = bounds(&p.positions);
        let position = root.push(attribute(
            positions,
            first * 12,
            count,
            accessor::ComponentType::F32,
            accessor::Type::Vec3,
            Some((min, max)),
        ));
        let normal = root.push(attribute(
            normals,
            first * 12,
            count,
            accessor::ComponentType::F32,
            accessor::Type::Vec3,
            None,
        ));
        let mut colour = attribute(
            colours,
            first * 4,
            count,
            accessor::ComponentType::U8,
            accessor::Type::Vec4,
            None,
        );
        colour.normalized = true;
        let colour = root.push(colour);
        let (component, size) = index_type(p);
        let length = p.indices.len() * size;
        let index_view = root.push(view(
            index_offset,
            length,
            None,
            buffer::Target::ElementArrayBuffer,
        ));
        index_offset += length.next_multiple_of(4);
        let indices = root.push(attribute(
            index_view,
            0,
            p.indices.len(),
            component,
            accessor::Type::Scalar,
            None,
        ));
        let name = p.material.map_or("mesh", |m| m.name());
        let material = root.push(json::Material {
            name: Some(name.to_owned()),
            pbr_metallic_roughness: material::PbrMetallicRoughness {
                base_color_factor: material::PbrBaseColorFactor([1.0, 1.0, 1.0, 1.0]),
                metallic_factor: material::StrengthFactor(0.0),
                roughness_factor: material::StrengthFactor(0.9),
                ..material::PbrMetallicRoughness::default()
            },
            ..json::Material::default()
        });
        let attributes = BTreeMap::from([
            (Valid(mesh::Semantic::Positions), position),
            (Valid(mesh::Semantic::Normals), normal),
            (Valid(mesh::Semantic::Colors(0)), colour),
        ]);
        primitives.push(mesh::Primitive {
            attributes,
            extensions: None,
            extras: None,
            indices: Some(indices),
            material: Some(material),
            mode: Valid(mesh::Mode::Triangles),
            targets: None,
        });
        first += count;
    }
    root.push(json::Buffer {
        byte_length: USize64::from(binary_len(layout)),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    });
    let mesh = root.push(json::Mesh {
        extensions: None,
        extras: None,
        name: Some("citymesh".to_owned()),
        primitives,
        weights: None,
    });
    let node = root.push(json::Node {
        mesh: Some(mesh),
        name: Some("citymesh".to_owned()),
        ..json::Node::default()
    });
    root.scenes.push(scene(vec![node], extras));
    root.scene = Some(Index::new(0));
    to_json(&root, &placed.node)
}

/// The length of the binary buffer: the attributes, then each primitive's indices padded to 4
/// bytes.
pub fn binary_len(layout: &IndexedLayout) -> usize {
    let vertices = layout.vertex_count();
    let indices: usize = layout
        .primitives
        .iter()
        .map(|p| (p.indices.len() * index_type(p).1).next_multiple_of(4))
        .sum();
    vertices * (12 + 12 + 4) + indices
}

/// Appends the binary buffer [`assemble`] describes ([`binary_len`] bytes) to `out`.
pub fn write_binary(layout: &IndexedLayout, out: &mut Vec<u8>) {
    let start = out.len();
    out.resize(start + binary_len(layout), 0);
    let mut rest = &mut out[start..];
    let mut take = |bytes: usize| {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(bytes);
        rest = tail;
        head
    };
    for p in &layout.primitives {
        write_vec3(take(p.positions.len() * 12), &p.positions);
    }
    for p in &layout.primitives {
        write_vec3(take(p.normals.len() * 12), &p.normals);
    }
    for p in &layout.primitives {
        for (d, c) in take(p.colours.len() * 4)
            .chunks_exact_mut(4)
            .zip(&p.colours)
        {
            d.copy_from_slice(c);
        }
    }
    for p in &layout.primitives {
        let size = index_type(p).1;
        let dst = take((p.indices.len() * size).next_multiple_of(4));
        if size == 2 {
            for (d, &i) in dst.chunks_exact_mut(2).zip(&p.indices) {
                // The layout's vertices fit u16 here, so the cast is exact.
                d.copy_from_slice(&(i as u16).to_le_bytes());
            }
        } else {
            for (d, &i) in dst.chunks_exact_mut(4).zip(&p.indices) {
                d.copy_from_slice(&i.to_le_bytes());
            }
        }
    }
}

fn write_vec3(dst: &mut [u8], values: &[[f32; 3]]) {
    for (d, v) in dst.chunks_exact_mut(12).zip(values) {
        d[0..4].copy_from_slice(&v[0].to_le_bytes());
        d[4..8].copy_from_slice(&v[1].to_le_bytes());
        d[8..12].copy_from_slice(&v[2].to_le_bytes());
    }
}

/// u16 indices when the primitive's vertices fit, else u32: the type and its size.
fn index_type(p: &LayoutPrimitive) -> (accessor::ComponentType, usize) {
    if p.positions.len() <= usize::from(u16::MAX) {
        (accessor::ComponentType::U16, 2)
    } else {
        (accessor::ComponentType::U32, 4)
    }
}

fn scene(nodes: Vec<Index<json::Node>>, extras: Value) -> json::Scene {
    json::Scene {
        extensions: None,
        extras: serde_json::value::to_raw_value(&extras).ok(),
        name: Some("citymesh".to_owned()),
        nodes,
    }
}

/// Where the content sits and which buildings it holds, for clients.
fn scene_extras(node: &NodePlacement, buildings: &[String]) -> Value {
    match *node {
        NodePlacement::Origin { lon, lat, height } => value!({
            "origin": {"lon": lon, "lat": lat, "height": height},
            "heightReference": "metres above mean sea level (EGM96 geoid, as SRTM)",
            "axes": "x = east, y = up, z = -north, metres from the origin (local frame on WGS84)",
            "buildings": buildings}),
        NodePlacement::EcefCentre(_) => value!({
            "axes": "ECEF (WGS84) metres relative to the node translation, z-up; heights above the ellipsoid are SRTM heights",
            "buildings": buildings}),
    }
}

/// The document as JSON bytes. `gltf-json` keeps node matrices in f32, which would move ECEF
/// content by up to half a metre, so the ECEF node's matrix is written here in f64.
fn to_json(root: &json::Root, node: &NodePlacement) -> Vec<u8> {
    let NodePlacement::EcefCentre(c) = *node else {
        return serde_json::to_vec(root).unwrap_or_default();
    };
    let mut doc = serde_json::to_value(root).unwrap_or(Value::Null);
    if let Some(n) = doc.pointer_mut("/nodes/0") {
        // z-up to y-up, then the centre (in y-up axes), column-major.
        n["matrix"] = value!([
            1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, c[0], c[2], -c[1], 1.0
        ]);
    }
    serde_json::to_vec(&doc).unwrap_or_default()
}

fn view(
    offset: usize,
    length: usize,
    stride: Option<usize>,
    target: buffer::Target,
) -> buffer::View {
    buffer::View {
        buffer: Index::new(0),
        byte_length: USize64::from(length),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: stride.map(buffer::Stride),
        name: None,
        target: Some(Valid(target)),
        extensions: None,
        extras: None,
    }
}

fn attribute(
    view: Index<buffer::View>,
    offset: usize,
    count: usize,
    component: accessor::ComponentType,
    kind: accessor::Type,
    bounds: Option<([f32; 3], [f32; 3])>,
) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: Some(USize64::from(offset)),
        count: USize64::from(count),
        component_type: Valid(accessor::GenericComponentType(component)),
        extensions: None,
        extras: None,
        type_: Valid(kind),
        min: bounds.map(|(min, _)| value!(min)),
        max: bounds.map(|(_, max)| value!(max)),
        name: None,
        normalized: false,
        sparse: None,
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

//! Stage 3 of the encoder: the glTF JSON document (built with `gltf-json`) and its binary
//! buffer.
//!
//! The buffer holds, in order: all positions (f32 VEC3), all normals (f32 VEC3), all colours
//! (normalised u8 VEC4), each a view shared by the primitives' accessors (hence a byte stride),
//! then each primitive's indices (u16 when its vertices fit, else u32) in a view of its own.

use super::layout::{IndexedLayout, LayoutPrimitive};
use super::placement::{NodePlacement, Placed};
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};
use json::{Index, accessor, buffer, material, mesh};
use serde_json::{Value, json as value};
use std::collections::BTreeMap;

const GENERATOR: &str = concat!("citymesh ", env!("CARGO_PKG_VERSION"));

/// The JSON bytes and the binary buffer of a layout.
pub fn assemble(
    layout: &IndexedLayout,
    placed: &Placed,
    buildings: &[String],
) -> (Vec<u8>, Vec<u8>) {
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
        return (to_json(&root, &placed.node), Vec::new());
    }

    let pos_len = vertices * 12;
    let col_len = vertices * 4;
    let index_len: usize = layout.primitives.iter().map(index_bytes).sum();
    let mut bin = Vec::with_capacity(pos_len * 2 + col_len + index_len + 4);
    for p in &layout.primitives {
        for v in &p.positions {
            v.iter()
                .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
        }
    }
    for p in &layout.primitives {
        for v in &p.normals {
            v.iter()
                .for_each(|c| bin.extend_from_slice(&c.to_le_bytes()));
        }
    }
    for p in &layout.primitives {
        for c in &p.colours {
            bin.extend_from_slice(c);
        }
    }
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
        let indices = push_indices(&mut root, &mut bin, p);
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
        byte_length: USize64::from(bin.len()),
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
    (to_json(&root, &placed.node), bin)
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
    let mut doc = serde_json::to_value(root).unwrap_or(Value::Null);
    if let NodePlacement::EcefCentre(c) = *node
        && let Some(n) = doc.pointer_mut("/nodes/0")
    {
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

fn index_bytes(p: &LayoutPrimitive) -> usize {
    let size = if p.positions.len() <= usize::from(u16::MAX) {
        2
    } else {
        4
    };
    (p.indices.len() * size).next_multiple_of(4)
}

/// Appends the primitive's indices to the buffer in a view of their own, u16 when they fit.
fn push_indices(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    p: &LayoutPrimitive,
) -> Index<json::Accessor> {
    let start = bin.len();
    let small = p.positions.len() <= usize::from(u16::MAX);
    if small {
        for &i in &p.indices {
            bin.extend_from_slice(&(i as u16).to_le_bytes());
        }
    } else {
        for &i in &p.indices {
            bin.extend_from_slice(&i.to_le_bytes());
        }
    }
    let length = bin.len() - start;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let view = root.push(view(
        start,
        length,
        None,
        buffer::Target::ElementArrayBuffer,
    ));
    let component = if small {
        accessor::ComponentType::U16
    } else {
        accessor::ComponentType::U32
    };
    root.push(attribute(
        view,
        0,
        p.indices.len(),
        component,
        accessor::Type::Scalar,
        None,
    ))
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

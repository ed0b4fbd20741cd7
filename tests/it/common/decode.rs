//! An independent reader of citymesh's GLBs in every encoding: meshopt views decoded with
//! meshoptimizer's decoder, accessors read by component type, positions through the node
//! matrix. What a client does, so tests can compare encodings triangle by triangle.

use serde_json::Value;

/// A GLB's JSON and BIN chunks.
pub fn chunks(glb: &[u8]) -> (Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json: Value = serde_json::from_slice(&glb[20..20 + json_len]).unwrap();
    let rest = &glb[20 + json_len..];
    let bin = if rest.len() >= 8 {
        let len = u32::from_le_bytes(rest[0..4].try_into().unwrap()) as usize;
        rest[8..8 + len].to_vec()
    } else {
        Vec::new()
    };
    (json, bin)
}

/// The same file with every `EXT_meshopt_compression` view decoded into one plain buffer (what
/// a client's decoder produces): a GLB the validator can check in full.
pub fn decode_meshopt(glb: &[u8]) -> Vec<u8> {
    let (mut json, bin) = chunks(glb);
    let Some(fallback) = json["buffers"]
        .get(1)
        .map(|b| b["byteLength"].as_u64().unwrap())
    else {
        return glb.to_vec();
    };
    let mut out = vec![0u8; fallback as usize];
    for view in json["bufferViews"].as_array_mut().unwrap() {
        let ext = view["extensions"]["EXT_meshopt_compression"].clone();
        if ext.is_null() {
            // Not compressed (property tables): its bytes move along into the one buffer.
            let at = view["byteOffset"].as_u64().unwrap() as usize;
            let bytes = &bin[at..at + view["byteLength"].as_u64().unwrap() as usize];
            while !out.len().is_multiple_of(8) {
                out.push(0);
            }
            view["byteOffset"] = out.len().into();
            out.extend_from_slice(bytes);
            continue;
        }
        let src = &bin[ext["byteOffset"].as_u64().unwrap() as usize..]
            [..ext["byteLength"].as_u64().unwrap() as usize];
        let (count, stride) = (
            ext["count"].as_u64().unwrap() as usize,
            ext["byteStride"].as_u64().unwrap() as usize,
        );
        let decoded: Vec<u8> = match (ext["mode"].as_str().unwrap(), stride) {
            ("TRIANGLES", 2) => meshopt::decode_index_buffer::<u16>(src, count)
                .unwrap()
                .iter()
                .flat_map(|i| i.to_le_bytes())
                .collect(),
            ("TRIANGLES", 4) => meshopt::decode_index_buffer::<u32>(src, count)
                .unwrap()
                .iter()
                .flat_map(|i| i.to_le_bytes())
                .collect(),
            ("ATTRIBUTES", 4) => meshopt::decode_vertex_buffer::<[u8; 4]>(src, count)
                .unwrap()
                .concat(),
            ("ATTRIBUTES", 8) => meshopt::decode_vertex_buffer::<[u8; 8]>(src, count)
                .unwrap()
                .concat(),
            other => panic!("unexpected meshopt view {other:?}"),
        };
        let at = view["byteOffset"].as_u64().unwrap() as usize;
        out[at..at + decoded.len()].copy_from_slice(&decoded);
        view["buffer"] = 0.into();
        view.as_object_mut().unwrap().remove("extensions");
    }
    json["buffers"] = serde_json::json!([{"byteLength": out.len()}]);
    let without = |list: &Value| -> Value {
        list.as_array()
            .unwrap()
            .iter()
            .filter(|e| *e != "EXT_meshopt_compression")
            .cloned()
            .collect::<Vec<Value>>()
            .into()
    };
    json["extensionsUsed"] = without(&json["extensionsUsed"]);
    json["extensionsRequired"] = without(&json["extensionsRequired"]);
    glb_of(&json, &out)
}

/// A GLB from a document and a buffer.
pub fn glb_of(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// One triangle as a client sees it: its corners through the node matrix (file axes, metres),
/// and its colour.
#[derive(Debug, Clone, PartialEq)]
pub struct Triangle {
    pub corners: [[f64; 3]; 3],
    /// Whether the file gave raw corners as whole numbers (quantized).
    pub raw: [[f64; 3]; 3],
    pub colour: [u8; 4],
    pub material: String,
    /// The feature id its corners carry (`_FEATURE_ID_0`; all three the same), if any.
    pub feature: Option<u32>,
}

/// Every triangle of a GLB in any encoding (meshopt decoded first).
pub fn triangles(glb: &[u8]) -> Vec<Triangle> {
    let (json, bin) = chunks(&decode_meshopt(glb));
    let matrix: Vec<f64> = json["nodes"][0]["matrix"].as_array().map_or_else(
        || {
            vec![
                1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
            ]
        },
        |m| m.iter().map(|v| v.as_f64().unwrap()).collect(),
    );
    let apply = |p: [f64; 3]| {
        [0, 1, 2].map(|r| {
            matrix[r] * p[0] + matrix[4 + r] * p[1] + matrix[8 + r] * p[2] + matrix[12 + r]
        })
    };
    let mut out = Vec::new();
    for prim in json["meshes"][0]["primitives"].as_array().unwrap() {
        let read = |accessor: u64| read_accessor(&json, &bin, accessor as usize);
        let positions = read(prim["attributes"]["POSITION"].as_u64().unwrap());
        let colours = read(prim["attributes"]["COLOR_0"].as_u64().unwrap());
        let indices = read(prim["indices"].as_u64().unwrap());
        let features = prim["attributes"]["_FEATURE_ID_0"].as_u64().map(read);
        let material = json["materials"][prim["material"].as_u64().unwrap() as usize]["name"]
            .as_str()
            .unwrap()
            .to_owned();
        for t in indices.chunks_exact(3) {
            let raw = [0, 1, 2].map(|k| {
                let p = &positions[t[k][0] as usize];
                [p[0], p[1], p[2]]
            });
            let c = &colours[t[0][0] as usize];
            let feature = features.as_ref().map(|f| {
                let [a, b, c] = [0, 1, 2].map(|k| f[t[k][0] as usize][0] as u32);
                assert!(
                    a == b && b == c,
                    "a triangle's corners name features {a}, {b}, {c}"
                );
                a
            });
            out.push(Triangle {
                corners: raw.map(apply),
                raw,
                colour: [0, 1, 2, 3].map(|k| (c[k] * 255.0).round() as u8),
                material: material.clone(),
                feature,
            });
        }
    }
    out
}

/// An accessor's elements as f64 (normalised types scaled to 0..1 or -1..1).
fn read_accessor(json: &Value, bin: &[u8], index: usize) -> Vec<Vec<f64>> {
    let a = &json["accessors"][index];
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let count = a["count"].as_u64().unwrap() as usize;
    let components = match a["type"].as_str().unwrap() {
        "SCALAR" => 1,
        "VEC3" => 3,
        "VEC4" => 4,
        t => panic!("type {t}"),
    };
    let component = a["componentType"].as_u64().unwrap();
    let size = match component {
        5120 | 5121 => 1,
        5122 | 5123 => 2,
        5125 | 5126 => 4,
        c => panic!("component {c}"),
    };
    let stride = view["byteStride"]
        .as_u64()
        .map_or(size * components, |s| s as usize);
    let start = view["byteOffset"].as_u64().unwrap_or(0) as usize
        + a["byteOffset"].as_u64().unwrap_or(0) as usize;
    let normalized = a["normalized"].as_bool().unwrap_or(false);
    (0..count)
        .map(|i| {
            (0..components)
                .map(|c| {
                    let at = start + i * stride + c * size;
                    let b = &bin[at..at + size];
                    let v = match component {
                        5120 => f64::from(b[0] as i8),
                        5121 => f64::from(b[0]),
                        5122 => f64::from(i16::from_le_bytes([b[0], b[1]])),
                        5123 => f64::from(u16::from_le_bytes([b[0], b[1]])),
                        5125 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                        _ => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    };
                    match (normalized, component) {
                        (true, 5120) => (v / 127.0).max(-1.0),
                        (true, 5121) => v / 255.0,
                        (true, 5123) => v / 65_535.0,
                        _ => v,
                    }
                })
                .collect()
        })
        .collect()
}

/// Checks a GLB's feature metadata the way a client reads it (the Khronos validator cannot look
/// inside `EXT_mesh_features` and `EXT_structural_metadata`): every feature id names a row or
/// is the declared null id, every building primitive has ids and the ground none, and every
/// property's views hold exactly `count` values (string offsets rising, the last one the end
/// of the strings). Returns the rows, with each property's values as text.
pub fn feature_rows(glb: &[u8]) -> Vec<serde_json::Map<String, Value>> {
    let (json, bin) = chunks(&decode_meshopt(glb));
    let Some(meta) = json["extensions"].get("EXT_structural_metadata") else {
        return Vec::new();
    };
    let table = &meta["propertyTables"][0];
    let count = table["count"].as_u64().unwrap() as usize;
    let class = &meta["schema"]["classes"][table["class"].as_str().unwrap()]["properties"];
    for prim in json["meshes"][0]["primitives"].as_array().unwrap() {
        let material = json["materials"][prim["material"].as_u64().unwrap() as usize]["name"]
            .as_str()
            .unwrap();
        let ids = &prim["extensions"]["EXT_mesh_features"]["featureIds"][0];
        let Some(accessor) = prim["attributes"]["_FEATURE_ID_0"].as_u64() else {
            assert_eq!(
                material, "ground",
                "a {material} primitive without feature ids"
            );
            continue;
        };
        assert_ne!(material, "ground");
        assert_eq!(ids["featureCount"].as_u64().unwrap() as usize, count);
        assert_eq!(ids["attribute"], 0);
        let null = ids["nullFeatureId"].as_u64();
        for v in read_accessor(&json, &bin, accessor as usize) {
            let id = v[0];
            assert_eq!(id.fract(), 0.0);
            assert!(
                (id as usize) < count || Some(id as u64) == null,
                "feature id {id} of {count}"
            );
        }
    }
    let view = |k: &Value| -> &[u8] {
        let v = &json["bufferViews"][k.as_u64().unwrap() as usize];
        assert_eq!(v["buffer"], 0);
        let at = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        assert_eq!(at % 8, 0, "property views start at a multiple of 8");
        &bin[at..at + v["byteLength"].as_u64().unwrap() as usize]
    };
    let mut rows = vec![serde_json::Map::new(); count];
    for (name, p) in table["properties"].as_object().unwrap() {
        let def = &class[name];
        let values = view(&p["values"]);
        let texts: Vec<String> =
            match (def["type"].as_str().unwrap(), def["componentType"].as_str()) {
                ("STRING", _) => {
                    let wide = p["stringOffsetType"] == "UINT32";
                    let raw = view(&p["stringOffsets"]);
                    let offsets: Vec<usize> = if wide {
                        raw.chunks_exact(4)
                            .map(|c| u32::from_le_bytes(c.try_into().unwrap()) as usize)
                            .collect()
                    } else {
                        raw.chunks_exact(2)
                            .map(|c| usize::from(u16::from_le_bytes(c.try_into().unwrap())))
                            .collect()
                    };
                    assert_eq!(offsets.len(), count + 1, "{name}");
                    assert_eq!(offsets[count], values.len(), "{name}");
                    assert!(offsets.windows(2).all(|w| w[0] <= w[1]), "{name}");
                    offsets
                        .windows(2)
                        .map(|w| String::from_utf8(values[w[0]..w[1]].to_vec()).unwrap())
                        .collect()
                }
                ("SCALAR", Some("FLOAT32")) => {
                    assert_eq!(values.len(), 4 * count, "{name}");
                    values
                        .chunks_exact(4)
                        .map(|c| f32::from_le_bytes(c.try_into().unwrap()).to_string())
                        .collect()
                }
                ("SCALAR", Some("FLOAT64")) => {
                    assert_eq!(values.len(), 8 * count, "{name}");
                    values
                        .chunks_exact(8)
                        .map(|c| f64::from_le_bytes(c.try_into().unwrap()).to_string())
                        .collect()
                }
                ("SCALAR", Some("INT64")) => {
                    assert_eq!(values.len(), 8 * count, "{name}");
                    values
                        .chunks_exact(8)
                        .map(|c| i64::from_le_bytes(c.try_into().unwrap()).to_string())
                        .collect()
                }
                ("BOOLEAN", _) => {
                    assert_eq!(values.len(), count.div_ceil(8), "{name}");
                    (0..count)
                        .map(|i| (values[i / 8] >> (i % 8) & 1 == 1).to_string())
                        .collect()
                }
                other => panic!("property {name} of type {other:?}"),
            };
        for (row, text) in rows.iter_mut().zip(texts) {
            row.insert(name.clone(), Value::String(text));
        }
    }
    rows
}

/// Asserts that every vertex of the ECEF content `glb` (named `uri`) lies inside the 3D Tiles
/// region `r` (radians, then metres), as a client reads both; answers how many vertices.
pub fn assert_inside_region(glb: &[u8], r: &[f64], uri: &str) -> usize {
    let mut vertices = 0;
    for t in triangles(glb) {
        for q in t.corners {
            let (lon, lat, h) = citymesh_core::geo::ecef_to_geodetic([q[0], -q[2], q[1]]);
            let (lon, lat) = (lon.to_radians(), lat.to_radians());
            assert!(
                (r[0]..=r[2]).contains(&lon)
                    && (r[1]..=r[3]).contains(&lat)
                    && (r[4]..=r[5]).contains(&h),
                "a {} vertex of {uri} at {lon}, {lat}, {h} lies outside {r:?}",
                t.material
            );
            vertices += 1;
        }
    }
    vertices
}

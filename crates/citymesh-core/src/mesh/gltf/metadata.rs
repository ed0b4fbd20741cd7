//! Feature metadata in a GLB: a property table (`EXT_structural_metadata`) with one row per
//! feature, which each vertex points at through its feature id (`EXT_mesh_features`, the
//! attribute `_FEATURE_ID_0`).
//!
//! A [`ClassDef`] says what a row holds; the same definition gives the schema a GLB embeds and
//! the one a 3D Tiles tileset declares. Property values are stored uncompressed in the GLB's
//! own buffer (also in `meshopt` files, whose compressed views they follow), each view starting
//! at a multiple of 8 bytes as the extension asks.

use serde_json::{Map, Value, json};

/// The id of citymesh's metadata schema.
pub const SCHEMA_ID: &str = "citymesh";

/// The feature id of a vertex that belongs to no feature (stored as f32, exact).
pub const NULL_FEATURE_ID: u32 = 16_777_215;

/// A property's type in the schema.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropertyType {
    /// UTF-8; the empty string means "not tagged".
    String,
    /// 32-bit float, with a value meaning "none".
    Float32 { no_data: Option<i32> },
    /// 64-bit float (degrees of latitude and longitude), always given.
    Float64,
    /// 64-bit signed integer.
    Int64,
    /// True or false, always given.
    Boolean,
}

/// One property of a class.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PropertyDef {
    /// The property's id (an identifier: letters, digits and `_`).
    pub name: &'static str,
    pub kind: PropertyType,
    pub description: &'static str,
    /// The semantic clients may also look it up by (CesiumJS styles do: a name that is no
    /// identifier, like `cesium#estimatedHeight`, is reached this way).
    pub semantic: Option<&'static str>,
}

/// A class of features and its properties, in column order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClassDef {
    pub id: &'static str,
    pub description: &'static str,
    pub properties: &'static [PropertyDef],
}

impl ClassDef {
    /// The schema declaring this class (`EXT_structural_metadata.schema`, or a tileset's
    /// `schema`).
    pub fn schema(&self) -> Value {
        self.schema_with(&|_| true)
    }

    /// The schema declaring this class with only the properties `keep` keeps (a GLB declares
    /// those its table holds: readers expect a column for every property of the class).
    fn schema_with(&self, keep: &dyn Fn(&PropertyDef) -> bool) -> Value {
        let mut properties = Map::new();
        for p in self.properties.iter().filter(|p| keep(p)) {
            let mut def = Map::new();
            def.insert("description".into(), json!(p.description));
            match p.kind {
                PropertyType::String => {
                    def.insert("type".into(), json!("STRING"));
                    def.insert("noData".into(), json!(""));
                }
                PropertyType::Float32 { no_data } => {
                    def.insert("type".into(), json!("SCALAR"));
                    def.insert("componentType".into(), json!("FLOAT32"));
                    if let Some(v) = no_data {
                        def.insert("noData".into(), json!(v));
                    } else {
                        def.insert("required".into(), json!(true));
                    }
                }
                PropertyType::Float64 => {
                    def.insert("type".into(), json!("SCALAR"));
                    def.insert("componentType".into(), json!("FLOAT64"));
                    def.insert("required".into(), json!(true));
                }
                PropertyType::Int64 => {
                    def.insert("type".into(), json!("SCALAR"));
                    def.insert("componentType".into(), json!("INT64"));
                    def.insert("required".into(), json!(true));
                }
                PropertyType::Boolean => {
                    def.insert("type".into(), json!("BOOLEAN"));
                    def.insert("required".into(), json!(true));
                }
            }
            if let Some(semantic) = p.semantic {
                def.insert("semantic".into(), json!(semantic));
            }
            properties.insert(p.name.into(), Value::Object(def));
        }
        json!({
            "id": SCHEMA_ID,
            "classes": {
                self.id: {"description": self.description, "properties": properties},
            },
        })
    }
}

/// The values of one property, a row per feature.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    Strings(Vec<String>),
    Float32(Vec<f32>),
    Float64(Vec<f64>),
    Int64(Vec<i64>),
    Booleans(Vec<bool>),
}

impl Column {
    /// Whether every value is the property's "none".
    fn is_all_no_data(&self, kind: PropertyType) -> bool {
        match (self, kind) {
            (Column::Strings(v), PropertyType::String) => v.iter().all(String::is_empty),
            (
                Column::Float32(v),
                PropertyType::Float32 {
                    no_data: Some(none),
                },
            ) => v.iter().all(|&x| x == none as f32),
            _ => false,
        }
    }

    fn len(&self) -> usize {
        match self {
            Column::Strings(v) => v.len(),
            Column::Float32(v) => v.len(),
            Column::Float64(v) => v.len(),
            Column::Int64(v) => v.len(),
            Column::Booleans(v) => v.len(),
        }
    }
}

/// The rows of a class: one column per property of the class, in its order.
#[derive(Debug, Clone, PartialEq)]
pub struct PropertyTable {
    pub class: &'static ClassDef,
    pub columns: Vec<Column>,
}

impl PropertyTable {
    /// Rows in the table.
    pub fn count(&self) -> usize {
        self.columns.first().map_or(0, Column::len)
    }

    /// Appends the table's views to `bin` (buffer 0) and their JSON to `views`, and returns the
    /// document's `EXT_structural_metadata` extension object.
    pub fn append_to(&self, bin: &mut Vec<u8>, views: &mut Vec<Value>) -> Value {
        let mut add = |bytes: &[u8], views: &mut Vec<Value>| {
            while !bin.len().is_multiple_of(8) {
                bin.push(0);
            }
            let at = bin.len();
            bin.extend_from_slice(bytes);
            views.push(json!({"buffer": 0, "byteOffset": at, "byteLength": bytes.len()}));
            views.len() - 1
        };
        let mut properties = Map::new();
        let mut kept = Vec::new();
        for (def, column) in self.class.properties.iter().zip(&self.columns) {
            if column.is_all_no_data(def.kind) {
                // An optional property with nothing to say is left out of the table and of the
                // schema this file declares (and costs nothing).
                continue;
            }
            kept.push(def.name);
            let property = match column {
                Column::Strings(values) => {
                    let data: Vec<u8> = values.iter().flat_map(|v| v.bytes()).collect();
                    // Offsets in 2 bytes when the strings fit, else 4.
                    let short = data.len() <= usize::from(u16::MAX);
                    let mut offsets = Vec::with_capacity(4 * (values.len() + 1));
                    let mut at = 0usize;
                    for len in std::iter::once(0).chain(values.iter().map(String::len)) {
                        at += len;
                        if short {
                            offsets.extend_from_slice(&(at as u16).to_le_bytes());
                        } else {
                            offsets.extend_from_slice(&(at as u32).to_le_bytes());
                        }
                    }
                    let values = add(&data, views);
                    let offsets = add(&offsets, views);
                    let kind = if short { "UINT16" } else { "UINT32" };
                    json!({"values": values, "stringOffsets": offsets, "stringOffsetType": kind})
                }
                Column::Float32(values) => {
                    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                    json!({"values": add(&data, views)})
                }
                Column::Float64(values) => {
                    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                    json!({"values": add(&data, views)})
                }
                Column::Int64(values) => {
                    let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                    json!({"values": add(&data, views)})
                }
                // A bitstream, the first row in the lowest bit of the first byte.
                Column::Booleans(values) => {
                    let mut data = vec![0u8; values.len().div_ceil(8)];
                    for (i, _) in values.iter().enumerate().filter(|(_, v)| **v) {
                        data[i / 8] |= 1 << (i % 8);
                    }
                    json!({"values": add(&data, views)})
                }
            };
            properties.insert(def.name.into(), property);
        }
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        json!({
            "schema": self.class.schema_with(&|p| kept.contains(&p.name)),
            "propertyTables": [{
                "name": self.class.id,
                "class": self.class.id,
                "count": self.count(),
                "properties": properties,
            }],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    static CLASS: ClassDef = ClassDef {
        id: "thing",
        description: "a test class",
        properties: &[
            PropertyDef {
                name: "label",
                kind: PropertyType::String,
                description: "a label",
                semantic: None,
            },
            PropertyDef {
                name: "size",
                kind: PropertyType::Float32 { no_data: Some(-1) },
                description: "a size",
                semantic: Some("thing#size"),
            },
            PropertyDef {
                name: "id",
                kind: PropertyType::Int64,
                description: "an id",
                semantic: None,
            },
        ],
    };

    #[test]
    fn a_table_writes_aligned_views_that_read_back() {
        let table = PropertyTable {
            class: &CLASS,
            columns: vec![
                Column::Strings(vec!["ab".into(), String::new(), "cde".into()]),
                Column::Float32(vec![1.5, -1.0, 2.0]),
                Column::Int64(vec![-7, 8, 1 << 40]),
            ],
        };
        let mut bin = vec![1u8; 5];
        let mut views = vec![json!({})];
        let ext = table.append_to(&mut bin, &mut views);
        assert_eq!(views.len(), 1 + 4);
        let view = |k: usize| {
            let v = &views[k];
            let at = v["byteOffset"].as_u64().unwrap() as usize;
            assert_eq!(at % 8, 0);
            &bin[at..at + v["byteLength"].as_u64().unwrap() as usize]
        };
        let label = &ext["propertyTables"][0]["properties"]["label"];
        assert_eq!(view(label["values"].as_u64().unwrap() as usize), b"abcde");
        let offsets: Vec<u16> = view(label["stringOffsets"].as_u64().unwrap() as usize)
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(offsets, [0, 2, 2, 5]);
        assert_eq!(label["stringOffsetType"], "UINT16");
        let ids: Vec<i64> = view(4)
            .chunks_exact(8)
            .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(ids, [-7, 8, 1 << 40]);
        assert_eq!(ext["propertyTables"][0]["count"], 3);
        let schema = &ext["schema"]["classes"]["thing"]["properties"];
        assert_eq!(schema["size"]["noData"], -1);
        assert_eq!(schema["size"]["semantic"], "thing#size");
        assert!(schema["label"].get("semantic").is_none());
        assert_eq!(schema["id"]["componentType"], "INT64");
        assert_eq!(bin.len() % 4, 0);
        // Optional columns with nothing in them are left out (a view may not be empty).
        let empty = PropertyTable {
            class: &CLASS,
            columns: vec![
                Column::Strings(vec![String::new(); 2]),
                Column::Float32(vec![-1.0; 2]),
                Column::Int64(vec![1, 2]),
            ],
        };
        let mut views = Vec::new();
        let ext = empty.append_to(&mut Vec::new(), &mut views);
        let props = ext["propertyTables"][0]["properties"].as_object().unwrap();
        assert_eq!(props.keys().collect::<Vec<_>>(), ["id"]);
        // The file's schema declares only what its table holds.
        let declared = ext["schema"]["classes"]["thing"]["properties"]
            .as_object()
            .unwrap();
        assert_eq!(declared.keys().collect::<Vec<_>>(), ["id"]);
        assert_eq!(views.len(), 1);
    }
}

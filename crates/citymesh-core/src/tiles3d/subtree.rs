//! Binary subtree files (3D Tiles 1.1, implicit tiling): a 24-byte header (magic `subt`, version
//! 1, JSON and binary lengths), the JSON chunk and the binary chunk, each padded to 8 bytes.
//! Availability bitstreams list each level's tiles in Morton order, levels one after another,
//! bits least significant first within a byte.

use super::regions::TileRegions;
use crate::geo::{ImplicitTile, morton};
use serde_json::{Value, json};

/// The header's magic, `subt` read as a little-endian u32.
pub const SUBTREE_MAGIC: &[u8; 4] = b"subt";

/// A bitstream, or `constant` when all bits are equal.
enum Availability {
    Constant(bool),
    Bits(Vec<u8>, usize),
}

fn availability(bits: &[bool]) -> Availability {
    let count = bits.iter().filter(|b| **b).count();
    if count == 0 || count == bits.len() {
        return Availability::Constant(count > 0);
    }
    let mut bytes = vec![0u8; bits.len().div_ceil(8)];
    for (i, &b) in bits.iter().enumerate() {
        if b {
            bytes[i / 8] |= 1 << (i % 8);
        }
    }
    Availability::Bits(bytes, count)
}

/// The class of the subtree's tile metadata in the tileset's schema: each tile's bounding region.
pub const TILE_CLASS: &str = "tile";
/// Its property with the semantic `TILE_BOUNDING_REGION`.
pub const TILE_REGION_PROPERTY: &str = "boundingRegion";
/// Its property with the semantic `TILE_GEOMETRIC_ERROR`.
pub const TILE_ERROR_PROPERTY: &str = "geometricError";

/// The one subtree of a tree whose leaves are at `regions.leaf_level`: every tile exists and has
/// content (its ground, with the buildings whose group's point it holds, coarser above the
/// leaves), so the ground has no notches. Each tile's bounding region, measured on its content,
/// and its geometric error are its tile metadata.
pub fn root_subtree(regions: &TileRegions) -> Vec<u8> {
    let root = ImplicitTile {
        level: 0,
        x: 0,
        y: 0,
    };
    let leaf_level = regions.leaf_level;
    write_subtree(
        root,
        leaf_level + 1,
        &|_| true,
        &|t| t.level <= leaf_level,
        &|_| false,
        Some(regions),
    )
}

/// The subtree rooted at `root` with `levels` levels: `tile` and `content` say which tiles
/// (absolute coordinates) exist and have content; `child` which subtrees below it exist. With
/// `regions` (for a subtree at the tree's root holding every tile), each tile's region is its
/// tile metadata.
pub fn write_subtree(
    root: ImplicitTile,
    levels: u8,
    tile: &dyn Fn(ImplicitTile) -> bool,
    content: &dyn Fn(ImplicitTile) -> bool,
    child: &dyn Fn(ImplicitTile) -> bool,
    regions: Option<&TileRegions>,
) -> Vec<u8> {
    let bits_of = |level: u8, f: &dyn Fn(ImplicitTile) -> bool| -> Vec<bool> {
        let n = 1u32 << level;
        let mut bits = vec![false; (n as usize) * (n as usize)];
        for y in 0..n {
            for x in 0..n {
                let t = ImplicitTile {
                    level: root.level + level,
                    x: (root.x << level) + x,
                    y: (root.y << level) + y,
                };
                bits[morton(x, y) as usize] = f(t);
            }
        }
        bits
    };
    let tiles: Vec<bool> = (0..levels).flat_map(|l| bits_of(l, tile)).collect();
    let contents: Vec<bool> = (0..levels).flat_map(|l| bits_of(l, content)).collect();
    let children = bits_of(levels, child);

    let mut binary: Vec<u8> = Vec::new();
    let mut views: Vec<Value> = Vec::new();
    let mut entry = |a: Availability| -> Value {
        match a {
            Availability::Constant(c) => json!({"constant": u8::from(c)}),
            Availability::Bits(bytes, count) => {
                while !binary.len().is_multiple_of(8) {
                    binary.push(0);
                }
                views.push(
                    json!({"buffer": 0, "byteOffset": binary.len(), "byteLength": bytes.len()}),
                );
                binary.extend_from_slice(&bytes);
                json!({"bitstream": views.len() - 1, "availableCount": count})
            }
        }
    };
    let tile_entry = entry(availability(&tiles));
    let content_entry = entry(availability(&contents));
    let child_entry = entry(availability(&children));
    while !binary.len().is_multiple_of(8) {
        binary.push(0);
    }
    // Tile metadata: one row per available tile, in availability order (level by level, Morton
    // order within a level), which is the order the regions are kept in.
    let available = tiles.iter().filter(|b| **b).count();
    let metadata = regions.filter(|r| r.all().count() == available && available == tiles.len());
    let table = metadata.map(|r| {
        let mut column = |values: &mut dyn Iterator<Item = f64>| {
            while !binary.len().is_multiple_of(8) {
                binary.push(0);
            }
            let at = binary.len();
            for v in values {
                binary.extend_from_slice(&v.to_le_bytes());
            }
            views.push(json!({"buffer": 0, "byteOffset": at, "byteLength": binary.len() - at}));
            views.len() - 1
        };
        let regions = column(&mut r.all().flat_map(|(region, _)| region.to_radians()));
        let errors = column(&mut r.all().map(|(_, e)| *e));
        json!([{
            "class": TILE_CLASS,
            "count": available,
            "properties": {
                TILE_REGION_PROPERTY: {"values": regions},
                TILE_ERROR_PROPERTY: {"values": errors},
            },
        }])
    });
    let mut doc = json!({
        "tileAvailability": tile_entry,
        "contentAvailability": [content_entry],
        "childSubtreeAvailability": child_entry,
    });
    if let Some(table) = table {
        doc["propertyTables"] = table;
        doc["tileMetadata"] = json!(0);
    }
    if !binary.is_empty() {
        doc["buffers"] = json!([{"byteLength": binary.len()}]);
        doc["bufferViews"] = Value::Array(views);
    }
    let mut json = serde_json::to_vec(&doc).unwrap_or_default();
    while !json.len().is_multiple_of(8) {
        json.push(b' ');
    }
    let mut out = Vec::with_capacity(24 + json.len() + binary.len());
    out.extend_from_slice(SUBTREE_MAGIC);
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(json.len() as u64).to_le_bytes());
    out.extend_from_slice(&(binary.len() as u64).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&binary);
    out
}

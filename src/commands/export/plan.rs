//! What an export writes, cut into units of work: each unit is a tile whose files one exporter
//! writes at a time, under a lease ([`super::claims`]). The plan is made the same way by every
//! exporter from the same data, so they agree on the units without talking to each other.
//!
//! - 3D Tiles: a unit per tileset file of the world tree (zooms 12, 9, 6, 3 and the root). A
//!   zoom-12 unit writes the leaves, the blocks and the tileset file of its 16 data tiles; a unit
//!   above writes its blocks and tileset file from the summaries its 64 children units left in
//!   the database, so it waits for them ([`Unit::parent`]).
//! - XYZ: a unit per zoom-12 tile (every tile of the zooms from 12 down under it), and one per
//!   tile of a zoom above 12. Units of XYZ wait for nothing.

use citymesh_core::geo::{GeoBbox, TileCoord, TileRange};
use citymesh_core::tiles3d::{BLOCK_ZOOM, DATA_ZOOM, next_file_zoom};
use std::collections::{BTreeMap, BTreeSet};

/// The zoom of the units that write leaves and data tiles (the deepest tileset files).
pub const UNIT_ZOOM: u8 = 12;

/// The tiles an export covers.
pub enum Scope {
    /// Every tile over a box (XYZ: ground where there is no building).
    Box(GeoBbox),
    /// The data tiles that hold buildings, by the zoom-12 tile over them.
    Data(BTreeMap<TileCoord, Vec<TileCoord>>),
}

impl Scope {
    /// The data tiles `tiles` (those meeting `bbox` when one is given).
    pub fn of_data_tiles(tiles: &[TileCoord], bbox: Option<&GeoBbox>) -> Self {
        let mut by_unit: BTreeMap<TileCoord, Vec<TileCoord>> = BTreeMap::new();
        for t in tiles {
            if bbox.is_some_and(|b| !t.bounds().intersects(b)) {
                continue;
            }
            by_unit.entry(ancestor(t, UNIT_ZOOM)).or_default().push(*t);
        }
        for list in by_unit.values_mut() {
            list.sort_unstable();
            list.dedup();
        }
        Scope::Data(by_unit)
    }

    /// The data tiles under a zoom-12 unit.
    pub fn data_tiles_of(&self, unit: &TileCoord) -> &[TileCoord] {
        match self {
            Scope::Data(map) => map.get(unit).map_or(&[], Vec::as_slice),
            Scope::Box(_) => &[],
        }
    }

    /// How many data tiles the export is made from.
    pub fn data_tile_count(&self) -> usize {
        match self {
            Scope::Data(map) => map.values().map(Vec::len).sum(),
            Scope::Box(_) => 0,
        }
    }
}

/// A unit of work as planned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unit {
    /// Its number in the plan: units are claimed in this order.
    pub id: i64,
    pub tile: TileCoord,
    /// The unit made from this one's summary (3D Tiles), done after it.
    pub parent: Option<i64>,
    /// Files it writes at most (the leaves and blocks of data tiles that turn out to hold no
    /// group are not written).
    pub files_est: i64,
}

/// The ancestor of `t` at zoom `z` (`t` itself at its own zoom).
pub fn ancestor(t: &TileCoord, z: u8) -> TileCoord {
    let shift = t.z - z;
    TileCoord {
        z,
        x: t.x >> shift,
        y: t.y >> shift,
    }
}

/// The zooms of the 3D Tiles units, deepest first: where the world tree's tileset files start.
pub fn unit_zooms() -> Vec<u8> {
    let mut zooms: Vec<u8> = std::iter::successors(Some(0u8), |&z| {
        Some(next_file_zoom(z)).filter(|&n| n <= UNIT_ZOOM)
    })
    .collect();
    zooms.reverse();
    zooms
}

/// The units of a 3D Tiles export of `scope` (which must be [`Scope::Data`]).
pub fn tiles3d_units(scope: &Scope) -> Vec<Unit> {
    let Scope::Data(map) = scope else {
        return Vec::new();
    };
    let zooms = unit_zooms();
    // Each level's tiles, with the files each writes at most.
    let mut levels: Vec<BTreeMap<TileCoord, i64>> = Vec::new();
    let mut below: BTreeSet<TileCoord> = BTreeSet::new();
    for (i, &z) in zooms.iter().enumerate() {
        let mut level = BTreeMap::new();
        if i == 0 {
            for (unit, data) in map {
                let mut blocks: BTreeSet<TileCoord> = BTreeSet::new();
                for d in data {
                    for bz in z..=DATA_ZOOM {
                        blocks.insert(ancestor(d, bz));
                    }
                }
                // Leaves, blocks, the tileset file.
                level.insert(*unit, 4 * data.len() as i64 + blocks.len() as i64 + 1);
            }
        } else {
            let child_zoom = zooms[i - 1];
            let mut content: BTreeMap<TileCoord, BTreeSet<TileCoord>> = BTreeMap::new();
            for c in &below {
                let entry = content.entry(ancestor(c, z)).or_default();
                for bz in z.max(BLOCK_ZOOM)..child_zoom {
                    entry.insert(ancestor(c, bz));
                }
            }
            for (t, blocks) in content {
                level.insert(t, blocks.len() as i64 + 1);
            }
        }
        below = level.keys().copied().collect();
        levels.push(level);
    }
    // Numbered deepest first, row by row; each names the unit above it.
    let mut ids: BTreeMap<TileCoord, i64> = BTreeMap::new();
    let mut next = 0i64;
    let mut units = Vec::new();
    for level in &levels {
        let mut tiles: Vec<(&TileCoord, &i64)> = level.iter().collect();
        tiles.sort_by_key(|(t, _)| (t.y, t.x));
        for (t, files) in tiles {
            ids.insert(*t, next);
            units.push(Unit {
                id: next,
                tile: *t,
                parent: None,
                files_est: *files,
            });
            next += 1;
        }
    }
    for unit in &mut units {
        if let Some(i) = zooms.iter().position(|&z| z == unit.tile.z)
            && let Some(&up) = zooms.get(i + 1)
        {
            unit.parent = ids.get(&ancestor(&unit.tile, up)).copied();
        }
    }
    units
}

/// The units of an XYZ export of zooms `from..=to` over `scope`.
pub fn xyz_units(scope: &Scope, from: u8, to: u8) -> Vec<Unit> {
    let mut tiles: Vec<TileCoord> = Vec::new();
    for z in from..=to.min(UNIT_ZOOM - 1) {
        match scope {
            Scope::Box(b) => tiles.extend(TileCoord::covering(b, z).tiles()),
            Scope::Data(map) => {
                let at: BTreeSet<TileCoord> = map.keys().map(|u| ancestor(u, z)).collect();
                tiles.extend(at);
            }
        }
    }
    if to >= UNIT_ZOOM {
        match scope {
            Scope::Box(b) => tiles.extend(TileCoord::covering(b, UNIT_ZOOM).tiles()),
            Scope::Data(map) => tiles.extend(map.keys().copied()),
        }
    }
    tiles.sort_by_key(|t| (t.z, t.y, t.x));
    tiles.dedup();
    tiles
        .into_iter()
        .enumerate()
        .map(|(i, tile)| Unit {
            id: i as i64,
            tile,
            parent: None,
            files_est: xyz_tiles(scope, &tile, from, to).len() as i64,
        })
        .collect()
}

/// The XYZ tiles unit `unit` writes: itself above zoom 12; at zoom 12, every tile of the zooms
/// `from.max(12)..=to` under it in the scope (under a data tile, or over one above them).
pub fn xyz_tiles(scope: &Scope, unit: &TileCoord, from: u8, to: u8) -> Vec<TileCoord> {
    if unit.z < UNIT_ZOOM {
        return vec![*unit];
    }
    let mut out = Vec::new();
    for z in from.max(UNIT_ZOOM)..=to {
        let shift = z - UNIT_ZOOM;
        match scope {
            Scope::Box(b) => {
                let c = TileCoord::covering(b, z);
                let range = TileRange {
                    z,
                    x0: c.x0.max(unit.x << shift),
                    x1: c.x1.min(((unit.x + 1) << shift) - 1),
                    y0: c.y0.max(unit.y << shift),
                    y1: c.y1.min(((unit.y + 1) << shift) - 1),
                };
                if range.x0 <= range.x1 && range.y0 <= range.y1 {
                    out.extend(range.tiles());
                }
            }
            Scope::Data(_) => {
                let data = scope.data_tiles_of(unit);
                if z <= DATA_ZOOM {
                    let at: BTreeSet<TileCoord> = data.iter().map(|d| ancestor(d, z)).collect();
                    out.extend(at);
                } else {
                    let s = z - DATA_ZOOM;
                    for d in data {
                        for y in (d.y << s)..((d.y + 1) << s) {
                            for x in (d.x << s)..((d.x + 1) << s) {
                                out.push(TileCoord { z, x, y });
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(z: u8, x: u32, y: u32) -> TileCoord {
        TileCoord { z, x, y }
    }

    #[test]
    fn units_nest_deepest_first_and_name_their_parent() {
        assert_eq!(unit_zooms(), [12, 9, 6, 3, 0]);
        // Two data tiles under one zoom-12 tile, one under its neighbour.
        let data = [t(14, 8576, 5624), t(14, 8577, 5624), t(14, 8580, 5624)];
        let scope = Scope::of_data_tiles(&data, None);
        let units = tiles3d_units(&scope);
        let tiles: Vec<(u8, u32, u32)> = units
            .iter()
            .map(|u| (u.tile.z, u.tile.x, u.tile.y))
            .collect();
        assert_eq!(
            tiles,
            [
                (12, 2144, 1406),
                (12, 2145, 1406),
                (9, 268, 175),
                (6, 33, 21),
                (3, 4, 2),
                (0, 0, 0)
            ]
        );
        let ids: Vec<i64> = units.iter().map(|u| u.id).collect();
        assert_eq!(ids, [0, 1, 2, 3, 4, 5]);
        let parents: Vec<Option<i64>> = units.iter().map(|u| u.parent).collect();
        assert_eq!(parents, [Some(2), Some(2), Some(3), Some(4), Some(5), None]);
        // The first: 8 leaves, 2 data tiles + 1 zoom-13 + 1 zoom-12 block, its file.
        assert_eq!(units[0].files_est, 8 + 2 + 1 + 1 + 1);
        // Zoom 9: blocks at 9, 10 and 11 (one each) and its file; above 9 only files.
        assert_eq!(units[2].files_est, 3 + 1);
        assert_eq!(units[3].files_est, 1);
    }

    #[test]
    fn xyz_units_cover_every_zoom_once() {
        let data = [t(14, 8576, 5624), t(14, 8577, 5624)];
        let scope = Scope::of_data_tiles(&data, None);
        let units = xyz_units(&scope, 11, 16);
        let all: Vec<TileCoord> = units
            .iter()
            .flat_map(|u| xyz_tiles(&scope, &u.tile, 11, 16))
            .collect();
        // z11 1, z12 1, z13 1, z14 2, z15 8, z16 32.
        assert_eq!(all.len(), 1 + 1 + 1 + 2 + 8 + 32);
        let distinct: BTreeSet<TileCoord> = all.iter().copied().collect();
        assert_eq!(distinct.len(), all.len());
        let est: i64 = units.iter().map(|u| u.files_est).sum();
        assert_eq!(est, all.len() as i64);
    }
}

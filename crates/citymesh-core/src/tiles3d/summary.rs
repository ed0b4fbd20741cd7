//! Summaries of the buildings under a tile of the world quadtree: what the tileset needs to list
//! a tile (its bounding region and geometric error) and what its coarse content draws (blocks),
//! without reading the buildings again.
//!
//! A data tile's summary (zoom [`DATA_ZOOM`]) is made from its building groups (those whose
//! representative point lies in it, as its content holds them) and the elevation model under
//! it; every coarser tile's from its four children's summaries alone. So each summary costs a
//! bounded amount of work and memory: one data tile's buildings, or four summaries of at most
//! [`BLOCK_CELLS`]² blocks each.
//!
//! A block merges the building groups whose representative points share a cell of a
//! [`BLOCK_CELLS`] x [`BLOCK_CELLS`] grid over the tile: one square prism with their footprint
//! area, at their area-weighted centre and area-weighted height (roofs flattened at their mean
//! height). From the distance a coarse level is drawn at, a block of small houses stays a block
//! of the same built area and height, not empty ground.

use crate::building::RoofMethod;
use crate::building::generate::record_outline;
use crate::building::set::{BuildingSet, ClusterInfo};
use crate::geo::{GeoBbox, LocalFrame, Region, TileCoord, mercator_y};
use crate::osm::{BuildingRecord, OsmId, Ring, RingNode};
use crate::terrain::{CellMask, ElevationModel};

/// The zoom of data tiles: the finest level whose content draws blocks (from the data tile's
/// own summary), the level above the buildings themselves.
pub const DATA_ZOOM: u8 = 14;

/// The deepest level of the world quadtree, the buildings in full detail: tiles of about 800 m
/// at 49° N, a quarter of a data tile each.
pub const LEAF_ZOOM: u8 = 15;

/// The coarsest level with content (tiles of about 50 km at 49° N): above it a tile's blocks
/// would be smaller than a pixel wherever it is drawn, so coarser tiles only lead to their
/// children.
pub const BLOCK_ZOOM: u8 = 9;

/// Cells per side of a tile's block grid.
pub const BLOCK_CELLS: u32 = 16;

/// A block's side is at most this share of its cell's, so blocks never touch (each stays one
/// group) and stay inside their cell.
const FILL: f64 = 0.9;

/// Slack around summarised content, metres: vertices are stored as f32 or quantized.
const SLACK_M: f64 = 0.5;

/// Building groups merged into one prism.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    /// The largest building merged into it: the id the block is picked and styled by.
    pub id: OsmId,
    pub largest_m2: f64,
    /// Groups merged.
    pub groups: u32,
    /// Footprint area, m².
    pub area_m2: f64,
    /// Area-weighted centre of the merged groups' representative points (degrees).
    pub lon: f64,
    pub lat: f64,
    /// Area-weighted height above the ground, roofs at their mean height (m).
    pub height_m: f64,
}

impl Block {
    /// Merges `other` into this one.
    fn absorb(&mut self, other: &Block) {
        let total = self.area_m2 + other.area_m2;
        if total > 0.0 {
            let w = other.area_m2 / total;
            self.lon += (other.lon - self.lon) * w;
            self.lat += (other.lat - self.lat) * w;
            self.height_m += (other.height_m - self.height_m) * w;
        }
        self.area_m2 = total;
        self.groups += other.groups;
        if other.largest_m2 > self.largest_m2 {
            self.largest_m2 = other.largest_m2;
            self.id = other.id;
        }
    }
}

/// What the world tileset knows of a tile without reading its buildings.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSummary {
    pub tile: TileCoord,
    /// Building groups under the tile.
    pub groups: u64,
    /// The region holding the tile's content and all its descendants' (radians are made from
    /// it when written): the tile's square, every group it holds whole, and the ground.
    pub region: Region,
    /// How far (degrees of longitude, latitude) a group reaches past its representative point:
    /// the content of a tile below a data tile lies within its square grown by this much.
    pub reach: (f64, f64),
    /// The largest height flattened roofs leave out (half the largest roof rise, m).
    pub roof_error_m: f64,
    /// How far the coarse ground grid lies from the elevation model (m; 0 for data tiles).
    pub ground_error_m: f64,
    /// The blocks of the tile's grid, by cell.
    pub blocks: Vec<(u16, Block)>,
    /// The cells of the tile's 16 x 16 ground grid over data tiles (rows from the south): a
    /// coarse tile draws ground where data is, not over its whole square.
    pub ground_cells: CellMask,
    /// A digest of the buildings the tile and its descendants are drawn from: for a data tile,
    /// every building of the set it was summarised from (its square and the margin its leaves
    /// read); above, its children's digests. Any edit of one of those buildings changes it.
    pub digest: u64,
}

/// FNV-1a, 64 bits: a digest that is the same on every machine and in every version.
#[derive(Clone, Copy)]
pub(crate) struct Fnv(pub u64);

impl Fnv {
    pub fn new() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    pub fn bytes(mut self, bytes: &[u8]) -> Self {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
        self
    }

    pub fn u64(self, v: u64) -> Self {
        self.bytes(&v.to_le_bytes())
    }
}

/// The digest of building records (ids, kinds, every ring node's id and coordinates, tags).
pub fn records_digest<'a>(records: impl IntoIterator<Item = &'a BuildingRecord>) -> u64 {
    let mut h = Fnv::new();
    for r in records {
        let (kind, id) = match r.id {
            crate::osm::OsmId::Way(id) => (0u64, id),
            crate::osm::OsmId::Relation(id) => (1, id),
        };
        h = h.u64(kind).u64(id as u64).u64(u64::from(r.is_part));
        for (role, rings) in [(2u64, &r.outers), (3, &r.inners)] {
            for ring in rings {
                h = h.u64(role).u64(ring.nodes.len() as u64);
                for n in &ring.nodes {
                    h = h
                        .u64(n.id.map_or(u64::MAX, |i| i as u64))
                        .u64(n.lon.to_bits())
                        .u64(n.lat.to_bits());
                }
            }
        }
        for (k, v) in &r.tags {
            h = h
                .u64(k.len() as u64)
                .bytes(k.as_bytes())
                .u64(v.len() as u64)
                .bytes(v.as_bytes());
        }
    }
    h.0
}

/// The cell of `tile`'s block grid that holds a point (Web Mercator cells, so a child's cells
/// nest in its parent's).
fn cell_of(tile: &TileCoord, lon: f64, lat: f64) -> u16 {
    let n = (1u64 << tile.z) as f64;
    let cells = f64::from(BLOCK_CELLS);
    let u = ((lon + 180.0) / 360.0 * n - f64::from(tile.x)) * cells;
    let v = (mercator_y(lat) * n - f64::from(tile.y)) * cells;
    let clamp = |f: f64| (f.floor().max(0.0) as u32).min(BLOCK_CELLS - 1);
    (clamp(v) * BLOCK_CELLS + clamp(u)) as u16
}

/// The bounds `[west, south, east, north]` of a cell of `tile`'s grid.
fn cell_bounds(tile: &TileCoord, cell: u16) -> [f64; 4] {
    let (cx, cy) = (u32::from(cell) % BLOCK_CELLS, u32::from(cell) / BLOCK_CELLS);
    let sub = TileCoord {
        z: tile.z + 4,
        x: tile.x * BLOCK_CELLS + cx,
        y: tile.y * BLOCK_CELLS + cy,
    };
    debug_assert_eq!(BLOCK_CELLS, 16, "cells are the tiles four zooms down");
    let b = sub.bounds();
    [b.min_lon(), b.min_lat(), b.max_lon(), b.max_lat()]
}

/// A group's footprint area (m²) and area-weighted height with roofs flattened (m), its tallest
/// point above the ground and the largest half roof rise: the parts where the group has any
/// (they are what is drawn), else its buildings.
fn group_figures(
    records: &[&BuildingRecord],
    frame: &LocalFrame,
    roof_method: RoofMethod,
) -> Option<(f64, f64, f64, f64, OsmId)> {
    let has_parts = records.iter().any(|r| r.is_part);
    let (mut area, mut weighted, mut tallest, mut roof, mut largest) =
        (0.0, 0.0, 0.0f64, 0.0f64, None);
    for r in records.iter().filter(|r| r.is_part == has_parts) {
        let Some(o) = record_outline(r, frame, roof_method) else {
            continue;
        };
        area += o.area;
        weighted += o.area * (o.height - o.roof_height / 2.0);
        tallest = tallest.max(o.height);
        roof = roof.max(o.roof_height / 2.0);
        if largest.is_none_or(|(a, _)| o.area > a) {
            largest = Some((o.area, r.id));
        }
    }
    let (_, id) = largest?;
    (area > 0.0).then(|| (area, weighted / area, tallest, roof, id))
}

impl TileSummary {
    /// The summary of data tile `tile` from the groups of `set` whose representative point it
    /// holds, over `model` (which should cover the tile and the groups). `None`: no group.
    pub fn of_data_tile(
        tile: TileCoord,
        set: &BuildingSet,
        model: &ElevationModel,
        roof_method: RoofMethod,
    ) -> Option<Self> {
        let groups: Vec<&ClusterInfo> = set.clusters_of_tile(&tile);
        if groups.is_empty() {
            return None;
        }
        let square = tile.bounds();
        let (lon, lat) = square.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let mut extent = square;
        let (mut reach_lon, mut reach_lat, mut tallest, mut roof_error) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let mut blocks: Vec<(u16, Block)> = Vec::new();
        for c in &groups {
            let [w, s, e, n] = c.bounds;
            let (px, py) = c.representative_point();
            reach_lon = reach_lon.max(px - w).max(e - px);
            reach_lat = reach_lat.max(py - s).max(n - py);
            if let Ok(b) = GeoBbox::new(w, s, e.max(w + 1e-9), n.max(s + 1e-9)) {
                extent = extent.union(&b);
            }
            let Some((area, height, top, roof, id)) =
                group_figures(&set.cluster_records(c), &frame, roof_method)
            else {
                continue;
            };
            tallest = tallest.max(top);
            roof_error = roof_error.max(roof);
            let block = Block {
                id,
                largest_m2: area,
                groups: 1,
                area_m2: area,
                lon: px,
                lat: py,
                height_m: height,
            };
            add_block(&mut blocks, cell_of(&tile, px, py), &block);
        }
        blocks.sort_by_key(|(c, _)| *c);
        let (lo, hi) = model.height_range_in(&extent);
        let mut records: Vec<&BuildingRecord> = set.records().iter().map(AsRef::as_ref).collect();
        records.sort_by_key(|r| r.id);
        let digest = records_digest(records);
        Some(Self {
            digest,
            tile,
            groups: groups.len() as u64,
            region: Region::of_bbox(&extent, lo, hi + tallest).grown(SLACK_M),
            reach: (reach_lon, reach_lat),
            roof_error_m: roof_error,
            // Its blocks stand on the coarse ground grid over the square.
            ground_error_m: crate::scene::LevelOfDetail::ground_error(&square, model),
            blocks,
            ground_cells: CellMask::ALL,
        })
    }

    /// The summary of `tile` from its children's (`children` are those that exist). Tiles with
    /// content (from [`BLOCK_ZOOM`]) take the ground under their square from `model` (which
    /// should cover it); coarser ones have none.
    pub fn of_children(
        tile: TileCoord,
        children: &[&TileSummary],
        model: Option<&ElevationModel>,
    ) -> Option<Self> {
        let mut region: Option<Region> = None;
        let (mut groups, mut roof_error, mut ground_error) = (0, 0.0f64, 0.0f64);
        let mut blocks: Vec<(u16, Block)> = Vec::new();
        let mut ground_cells = CellMask::NONE;
        let mut digest = Fnv::new();
        for child in children {
            digest = digest
                .u64(u64::from(child.tile.x))
                .u64(u64::from(child.tile.y))
                .u64(child.digest);
            // The child's quadrant of this tile's grid: its cells halved.
            let (dx, dy) = (child.tile.x & 1, child.tile.y & 1);
            for row in 0..16 {
                for column in 0..16 {
                    if child.ground_cells.contains(column, row) {
                        ground_cells.insert(dx * 8 + column / 2, (1 - dy) * 8 + row / 2);
                    }
                }
            }
            groups += child.groups;
            roof_error = roof_error.max(child.roof_error_m);
            ground_error = ground_error.max(child.ground_error_m);
            region = Some(region.map_or(child.region, |r| r.union(&child.region)));
            for (_, b) in &child.blocks {
                add_block(&mut blocks, cell_of(&tile, b.lon, b.lat), b);
            }
        }
        let mut region = region?;
        if tile.z < BLOCK_ZOOM {
            blocks.clear();
        } else if let Some(model) = model {
            let square = tile.bounds();
            let tallest = blocks.iter().map(|(_, b)| b.height_m).fold(0.0, f64::max);
            // The ground drawn: the grid's cells over data (linear in degrees, as drawn).
            let (dx, dy) = (
                (square.max_lon() - square.min_lon()) / 16.0,
                (square.max_lat() - square.min_lat()) / 16.0,
            );
            for row in 0..16 {
                for column in 0..16 {
                    if !ground_cells.contains(column, row) {
                        continue;
                    }
                    let (w, s) = (
                        square.min_lon() + dx * f64::from(column),
                        square.min_lat() + dy * f64::from(row),
                    );
                    if let Ok(cell) = GeoBbox::new(w, s, w + dx, s + dy) {
                        let (lo, hi) = model.height_range_in(&cell);
                        region =
                            region.union(&Region::of_bbox(&cell, lo, hi + tallest).grown(SLACK_M));
                    }
                }
            }
            ground_error =
                ground_error.max(crate::scene::LevelOfDetail::ground_error(&square, model));
        }
        blocks.sort_by_key(|(c, _)| *c);
        Some(Self {
            digest: digest.0,
            tile,
            groups,
            region,
            reach: (0.0, 0.0),
            roof_error_m: roof_error,
            ground_error_m: ground_error,
            blocks,
            ground_cells,
        })
    }

    /// The version of `tile`'s content: for a tile at or above the data tiles (drawn from this,
    /// its own summary, alone) a digest of the whole summary; for a leaf below this data tile
    /// (drawn from the buildings around it) the digest of those buildings and the leaf.
    pub fn content_version(&self, tile: &TileCoord) -> u64 {
        if tile.z > DATA_ZOOM {
            Fnv::new()
                .u64(self.digest)
                .u64(u64::from(tile.z))
                .u64(u64::from(tile.x))
                .u64(u64::from(tile.y))
                .0
        } else {
            Fnv::new().bytes(&self.to_bytes()).0
        }
    }

    /// Whether the tile draws blocks (from [`BLOCK_ZOOM`] to the data tiles).
    pub fn draws_blocks(&self) -> bool {
        (BLOCK_ZOOM..=DATA_ZOOM).contains(&self.tile.z)
    }

    /// The region of `tile`, a tile below this data tile: its square grown by the groups'
    /// reach, at this summary's heights.
    pub fn region_below(&self, tile: &TileCoord) -> Region {
        let b = tile.bounds();
        let (rx, ry) = self.reach;
        let grown = Region {
            west: b.min_lon() - rx,
            south: b.min_lat() - ry,
            east: b.max_lon() + rx,
            north: b.max_lat() + ry,
            min_height: self.region.min_height,
            max_height: self.region.max_height,
        }
        .grown(SLACK_M);
        // Within the data tile's own region, which holds all of its content (with its slack).
        Region {
            west: grown.west.max(self.region.west),
            south: grown.south.max(self.region.south),
            east: grown.east.min(self.region.east),
            north: grown.north.min(self.region.north),
            min_height: self.region.min_height,
            max_height: self.region.max_height,
        }
    }

    /// The blocks as building records: square, flat-roofed prisms of each block's area (at most
    /// [`FILL`] of its cell's side), inside their cell, tagged with the block's height.
    pub fn block_records(&self) -> Vec<BuildingRecord> {
        self.blocks
            .iter()
            .map(|(cell, b)| {
                let [w, s, e, n] = cell_bounds(&self.tile, *cell);
                let frame = LocalFrame::new(b.lon, b.lat, 0.0);
                let (mx, my) = frame.metres_per_degree();
                let cell_side = ((e - w) * mx).min((n - s) * my);
                let side = b.area_m2.sqrt().min(FILL * cell_side);
                let (hx, hy) = (side / 2.0 / mx, side / 2.0 / my);
                let cx = b.lon.clamp(w + hx, e - hx);
                let cy = b.lat.clamp(s + hy, n - hy);
                let node = |lon: f64, lat: f64| RingNode { id: None, lon, lat };
                let ring = Ring {
                    nodes: vec![
                        node(cx - hx, cy - hy),
                        node(cx + hx, cy - hy),
                        node(cx + hx, cy + hy),
                        node(cx - hx, cy + hy),
                    ],
                };
                let mut tags = crate::osm::Tags::new();
                tags.insert("building".into(), "yes".into());
                tags.insert("roof:shape".into(), "flat".into());
                tags.insert("height".into(), format!("{:.2}", b.height_m.max(1.0)));
                tags.insert("citymesh:merged_groups".into(), b.groups.to_string());
                BuildingRecord {
                    id: b.id,
                    is_part: false,
                    outers: vec![ring],
                    inners: Vec::new(),
                    tags,
                }
            })
            .collect()
    }

    /// The horizontal error of merging a cell's groups into one block (m): a cell's diagonal.
    /// A block lies inside its cell and stands for every group whose representative point is
    /// in it, so a wall anywhere in the cell may be drawn up to that far from where it is (half
    /// a side would be the error of moving one building to its cell's centre, not that of
    /// leaving out many small ones).
    pub fn block_error_m(&self) -> f64 {
        let b = self.tile.bounds();
        let (lon, lat) = b.center();
        let (mx, my) = LocalFrame::new(lon, lat, 0.0).metres_per_degree();
        let cells = f64::from(BLOCK_CELLS);
        let width = (b.max_lon() - b.min_lon()) * mx / cells;
        let height = (b.max_lat() - b.min_lat()) * my / cells;
        width.hypot(height)
    }
}

/// Adds `block` to the block of `cell`.
fn add_block(blocks: &mut Vec<(u16, Block)>, cell: u16, block: &Block) {
    match blocks.iter_mut().find(|(c, _)| *c == cell) {
        Some((_, b)) => b.absorb(block),
        None => blocks.push((cell, *block)),
    }
}

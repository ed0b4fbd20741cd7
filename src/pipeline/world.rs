//! The world tileset's content, as the server answers it and `citymesh export` writes it: block
//! tiles (zooms 9 to 14) drawn from a tile's summary alone, and leaves (zoom 15) drawn from the
//! buildings the source holds around them.

use super::{Buildings, Generated, Generator, MeshOptions, gather, generate};
use crate::error::AppError;
use crate::source::AreaBuildings;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::TileCoord;
use citymesh_core::mesh::Encoding;
use citymesh_core::scene::SceneArea;
use citymesh_core::terrain::CellMask;
use citymesh_core::tiles3d::TileSummary;
use serde_json::json;
use std::sync::Arc;

/// The way from the root tileset file to the tree's files (`tileset.json` beside `world/`).
pub const ROOT_PREFIX: &str = "world/";

/// The way from a tileset file below the root (`world/{z}/{x}/`) to the tree's files.
pub const FILE_PREFIX: &str = "../../";

/// The buildings a block tile draws: its summary's blocks, one prism per cell.
pub async fn block_buildings(summary: Arc<TileSummary>) -> Result<AreaBuildings, AppError> {
    let set =
        tokio::task::spawn_blocking(move || BuildingSet::new(summary.block_records())).await?;
    Ok(AreaBuildings::given(Arc::new(set)))
}

/// A block tile's content: `buildings` (from [`block_buildings`]) on the coarse ground over the
/// cells `ground` (the summary's `ground_cells`). Roofs are flat whatever is asked.
pub async fn block_content(
    generator: &Generator,
    tile: TileCoord,
    ground: CellMask,
    buildings: AreaBuildings,
    encoding: Encoding,
) -> Result<Generated, AppError> {
    generate(
        generator,
        SceneArea::Blocks { tile, ground },
        Buildings::Loaded(buildings),
        None,
        MeshOptions::new(generator, encoding),
    )
    .await
}

/// A leaf's content with roofs from the tags and the named properties (what
/// `/3dtiles/world/15/{x}/{y}.glb` answers without a query).
pub async fn leaf_content(
    generator: &Generator,
    tile: TileCoord,
    encoding: Encoding,
) -> Result<Generated, AppError> {
    let area = SceneArea::World(tile);
    let buildings = gather(generator, area).await?;
    generate(
        generator,
        area,
        Buildings::Loaded(buildings),
        None,
        MeshOptions::new(generator, encoding),
    )
    .await
}

/// `tile` with its content version salted with the data version (generator, DEM, source), so
/// a content URL names everything its bytes are made from.
pub fn versioned(
    mut tile: citymesh_core::tiles3d::WorldTile,
    data_version: &str,
) -> citymesh_core::tiles3d::WorldTile {
    let seed = xxhash_rust::xxh3::xxh3_64(data_version.as_bytes());
    tile.version = tile
        .version
        .map(|v| xxhash_rust::xxh3::xxh3_64_with_seed(&v.to_le_bytes(), seed));
    tile
}

/// The version a content URL names (`?v=`), as written.
pub fn version_text(version: u64) -> String {
    format!("{version:016x}")
}

/// The root tileset file's `asset.extras`: how many data tiles the tree was made from, the
/// extent of its buildings (`root`: the summary of tile 0/0/0), and the last replication diff
/// in the data.
pub fn root_extras(
    data_tiles: usize,
    root: Option<&TileSummary>,
    replication: Option<&crate::source::data_tiles::ReplicationState>,
) -> serde_json::Value {
    let mut v = json!({
        "citymesh": {
            "dataTiles": data_tiles,
            "extent": root.map(|s| {
                let r = s.region;
                [r.west, r.south, r.east, r.north]
            }),
        }
    });
    // How fresh the data is: the last replication diff applied, when one was.
    if let Some(r) = replication {
        v["citymesh"]["replication"] = json!({"sequence": r.sequence, "timestamp": r.timestamp});
    }
    v
}

//! One change file applied to the imported data tiles, in one transaction with the sequence
//! number it brings (so a crash at any point leaves the store before or after the diff, never
//! between), and the generated content over every changed building's old and new outline
//! dropped after it.
//!
//! The steps: the element index names the data tiles holding what the change touches; the
//! core rebuilds those buildings (`citymesh_core::osm::rebuild`); every data tile either their
//! old or their new outline overlaps is written again; the areas (outlines grown by the data
//! margin, as a tile reads its buildings) are noted in the same transaction, then dropped from
//! the tile store and forgotten ([`drop_pending`]).

use super::super::data_tile::{DATA_ZOOM, MARGIN_DEGREES};
use super::super::store::{OsmTileStore, ReplicationState};
use super::elements_of;
use crate::cache::TileStore;
use citymesh_core::geo::{GeoBbox, TileCoord};
use citymesh_core::osm::{
    BuildingRecord, ChangeError, Lookups, OsmBuildings, OsmChange, pack, rebuild, touched_part,
    unpack, update_tile,
};
use std::collections::BTreeSet;

/// Why a change was not applied (nothing of it was).
#[derive(Debug, thiserror::Error)]
pub enum ApplyError {
    #[error("{0}")]
    Change(#[from] ChangeError),
    #[error("a stored data tile cannot be read: {0}")]
    Stored(#[from] citymesh_core::osm::OsmError),
    #[error("the database: {0}")]
    Database(#[from] sqlx::Error),
    #[error(
        "this store holds no imported data that can follow changes: import OSM data with this \
         citymesh first (an import by an older one keeps no element index; import it again)"
    )]
    NotIndexed,
    #[error("the work was cancelled: {0}")]
    Join(#[from] tokio::task::JoinError),
}

/// What one diff did.
#[derive(Debug, Default, Clone, PartialEq, serde::Serialize)]
pub struct DiffReport {
    /// The sequence number applied (none for a file applied by hand without one).
    pub sequence: Option<i64>,
    /// Elements the change file names (repeats counted).
    pub elements: u64,
    /// Buildings (and parts) changed, added or removed.
    pub buildings_changed: usize,
    /// Buildings the change adds outside the imported extent (not stored).
    pub outside_extent: usize,
    /// Data tiles written again.
    pub data_tiles_written: usize,
    /// Generated tiles (XYZ, 3D Tiles, scenes' rows) dropped.
    pub tiles_dropped: u64,
    pub seconds: f64,
    /// The areas made stale (each changed building's outlines grown by the data margin).
    #[serde(skip)]
    pub areas: Vec<GeoBbox>,
}

/// The data tiles (zoom 14) a box overlaps.
fn data_tiles_over(b: &[f64; 4]) -> Vec<TileCoord> {
    if !b.iter().all(|v| v.is_finite()) || b[0] > b[2] || b[1] > b[3] {
        return Vec::new();
    }
    let nw = TileCoord::containing(DATA_ZOOM, b[0], b[3]);
    let se = TileCoord::containing(DATA_ZOOM, b[2], b[1]);
    (nw.x..=se.x)
        .flat_map(|x| (nw.y..=se.y).map(move |y| TileCoord { z: DATA_ZOOM, x, y }))
        .collect()
}

fn grown(b: &[f64; 4]) -> Option<GeoBbox> {
    GeoBbox::new(b[0], b[1], b[2], b[3])
        .ok()
        .map(|g| g.grown_by_degrees(MARGIN_DEGREES))
}

/// Applies `change` to the imported data tiles of `store`, recording `state` (when given) in
/// the same transaction, then drops the generated content it made stale from `tiles`. A state
/// whose sequence is not above the stored one is not applied again (`Ok(None)`).
pub async fn apply_change(
    store: &OsmTileStore,
    tiles: &TileStore,
    change: OsmChange,
    state: Option<ReplicationState>,
) -> Result<Option<DiffReport>, ApplyError> {
    let started = std::time::Instant::now();
    if !store.is_indexed().await? {
        return Err(ApplyError::NotIndexed);
    }
    let mut w = store.import_writer().await?;
    if let (Some(new), Some(held)) = (&state, w.replication_state().await?)
        && new.sequence <= held.sequence
    {
        return Ok(None);
    }
    let mut report = DiffReport {
        sequence: state.as_ref().map(|s| s.sequence),
        elements: change.elements,
        ..DiffReport::default()
    };
    // The data tiles holding what the change touches.
    let lookups = Lookups::of(&change);
    let mut candidates: BTreeSet<TileCoord> = BTreeSet::new();
    use super::super::store::ElementKind as K;
    candidates.extend(
        w.tiles_holding(K::Node, lookups.nodes.iter().copied())
            .await?,
    );
    candidates.extend(
        w.tiles_holding(K::Way, lookups.ways.iter().copied())
            .await?,
    );
    candidates.extend(
        w.tiles_holding(K::Relation, lookups.relations.iter().copied())
            .await?,
    );
    // Only what the change may touch is kept of each tile: a diff over many tiles holds one
    // tile at a time.
    let change = std::sync::Arc::new(change);
    let lookups = std::sync::Arc::new(lookups);
    let mut parts: Vec<OsmBuildings> = Vec::new();
    for t in candidates {
        if let Some(body) = w.get_body(&t).await? {
            let (c, l) = (change.clone(), lookups.clone());
            let part = tokio::task::spawn_blocking(move || {
                unpack(&body).map(|tile| touched_part(&tile, &c, &l))
            })
            .await??;
            parts.push(part);
        }
    }
    let c = change.clone();
    let rebuilt = tokio::task::spawn_blocking(move || {
        let tiles: Vec<&OsmBuildings> = parts.iter().collect();
        rebuild(&tiles, &c)
    })
    .await??;

    // Every data tile an old or a new outline overlaps, of the imported extent.
    let mut targets: BTreeSet<TileCoord> = BTreeSet::new();
    for b in &rebuilt.old_bounds {
        targets.extend(data_tiles_over(b));
    }
    let new_tiles: Vec<(&BuildingRecord, Vec<TileCoord>)> = rebuilt
        .now
        .buildings
        .iter()
        .map(|r| {
            (
                r,
                data_tiles_over(&citymesh_core::building::cluster::record_bounds(r)),
            )
        })
        .collect();
    for (_, ts) in &new_tiles {
        targets.extend(ts.iter().copied());
    }
    let replaced = rebuilt.replaced();
    let mut imported: BTreeSet<TileCoord> = BTreeSet::new();
    for t in &targets {
        let Some(body) = w.get_body(t).await? else {
            continue;
        };
        imported.insert(*t);
        let mut tile = unpack(&body)?;
        let add: Vec<&BuildingRecord> = new_tiles
            .iter()
            .filter(|(_, ts)| ts.contains(t))
            .map(|(r, _)| *r)
            .collect();
        let skipped_here: Vec<_> = rebuilt
            .now
            .skipped
            .iter()
            .filter(|s| {
                s.bounds
                    .is_some_and(|b| data_tiles_over(&b).first() == Some(t))
            })
            .copied()
            .collect();
        update_tile(&mut tile, &rebuilt, &replaced, &add, &skipped_here);
        w.put_many(&[(*t, pack(&tile))]).await?;
        report.data_tiles_written += 1;
        let added = OsmBuildings {
            buildings: add.into_iter().cloned().collect(),
            member_ways: rebuilt.now.member_ways.clone(),
            ..OsmBuildings::default()
        };
        w.index_elements(t, elements_of(&added)).await?;
    }
    report.outside_extent = new_tiles
        .iter()
        .filter(|(_, ts)| !ts.iter().any(|t| imported.contains(t)))
        .count();
    report.buildings_changed = replaced.len();
    // The stale areas: each changed building's old and new outline, grown by the margin.
    let mut areas: Vec<GeoBbox> = rebuilt.old_bounds.iter().filter_map(grown).collect();
    areas.extend(
        new_tiles
            .iter()
            .filter(|(_, ts)| ts.iter().any(|t| imported.contains(t)))
            .filter_map(|(r, _)| grown(&citymesh_core::building::cluster::record_bounds(r))),
    );
    w.note_changed_areas(&areas).await?;
    report.areas = areas;
    if let Some(state) = &state {
        w.set_replication_state(state).await?;
    }
    w.commit().await?;
    report.tiles_dropped = drop_pending(store, tiles).await?;
    report.seconds = started.elapsed().as_secs_f64();
    Ok(Some(report))
}

/// Drops the generated content over every area a diff noted stale (this one's, and any a
/// crash left), then forgets the areas; answers how many generated tiles went.
pub async fn drop_pending(store: &OsmTileStore, tiles: &TileStore) -> Result<u64, sqlx::Error> {
    let pending = store.pending_areas().await?;
    let mut dropped = 0;
    for (_, area) in &pending {
        dropped += tiles.delete_overlapping(area).await?;
    }
    let ids: Vec<i64> = pending.iter().map(|(id, _)| *id).collect();
    store.clear_areas(&ids).await?;
    Ok(dropped)
}

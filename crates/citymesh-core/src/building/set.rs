//! A set of buildings ready to serve: the records, their clusters, and a grid over the clusters'
//! extents to find those of an area or a tile quickly.
//!
//! Each cluster has one representative point, the centre of its bounding box; a tile holds the
//! clusters whose point lies in it, so every building lands in exactly one tile, whole.
//!
//! Records are shared (`Arc`): sets made from the same parsed data hold the same records, not
//! copies of them.

use super::cluster::{clusters, record_bounds};
use crate::geo::{GeoBbox, ImplicitTile, TileCoord};
use crate::osm::BuildingRecord;
use foldhash::HashMap;
use std::collections::BTreeSet;
use std::sync::Arc;

/// Grid cell size in degrees (about 500 m).
const CELL: f64 = 0.005;

/// One cluster: its records (indices) and extent.
#[derive(Debug, Clone)]
pub struct ClusterInfo {
    pub records: Vec<usize>,
    /// (min lon, min lat, max lon, max lat).
    pub bounds: [f64; 4],
}

impl ClusterInfo {
    /// The point that decides the cluster's tile: the centre of its bounding box.
    pub fn representative_point(&self) -> (f64, f64) {
        super::in_box::bounds_centre(self.bounds)
    }

    /// The XYZ tile of zoom `z` this cluster belongs to: the one holding its point.
    pub fn xyz_tile(&self, z: u8) -> TileCoord {
        let (lon, lat) = self.representative_point();
        TileCoord::containing(z, lon, lat)
    }

    /// The tile at `level` of the implicit quadtree over `root` this cluster belongs to: the one
    /// holding its point; `None` when the point lies outside the root (another tree's cluster).
    pub fn implicit_tile(&self, root: &GeoBbox, level: u8) -> Option<ImplicitTile> {
        let (lon, lat) = self.representative_point();
        root.contains(lon, lat)
            .then(|| ImplicitTile::containing(root, level, lon, lat))
    }
}

/// Buildings with their clusters and a spatial index.
#[derive(Debug, Clone, Default)]
pub struct BuildingSet {
    records: Vec<Arc<BuildingRecord>>,
    clusters: Vec<ClusterInfo>,
    grid: HashMap<(i64, i64), Vec<u32>>,
}

fn cell(lon: f64, lat: f64) -> (i64, i64) {
    ((lon / CELL).floor() as i64, (lat / CELL).floor() as i64)
}

impl BuildingSet {
    /// Indexes records. Records with no outer ring or no finite coordinates are left out.
    pub fn new(records: Vec<BuildingRecord>) -> Self {
        Self::from_shared(records.into_iter().map(Arc::new).collect())
    }

    /// Indexes shared records, as [`BuildingSet::new`] does, without copying them.
    pub fn from_shared(records: Vec<Arc<BuildingRecord>>) -> Self {
        let records: Vec<Arc<BuildingRecord>> = records
            .into_iter()
            .filter(|r| {
                let b = record_bounds(r);
                b.iter().all(|v| v.is_finite()) && b[0] <= b[2] && b[1] <= b[3]
            })
            .collect();
        let mut out = Self {
            clusters: clusters(&records)
                .into_iter()
                .map(|c| {
                    let bounds = c.iter().map(|&i| record_bounds(&records[i])).fold(
                        [f64::MAX, f64::MAX, f64::MIN, f64::MIN],
                        |a, b| {
                            [
                                a[0].min(b[0]),
                                a[1].min(b[1]),
                                a[2].max(b[2]),
                                a[3].max(b[3]),
                            ]
                        },
                    );
                    ClusterInfo { records: c, bounds }
                })
                .collect(),
            records,
            grid: HashMap::default(),
        };
        for (i, c) in out.clusters.iter().enumerate() {
            let [x0, y0, x1, y1] = c.bounds;
            let ((cx0, cy0), (cx1, cy1)) = (cell(x0, y0), cell(x1, y1));
            // A cluster larger than 100 x 100 cells (50 km) is data gone wrong: index its point.
            let cells = if (cx1 - cx0 + 1) * (cy1 - cy0 + 1) > 10_000 {
                let (x, y) = c.representative_point();
                vec![cell(x, y)]
            } else {
                (cx0..=cx1)
                    .flat_map(|cx| (cy0..=cy1).map(move |cy| (cx, cy)))
                    .collect()
            };
            for k in cells {
                out.grid.entry(k).or_default().push(i as u32);
            }
        }
        out
    }

    pub fn records(&self) -> &[Arc<BuildingRecord>] {
        &self.records
    }

    /// Bytes the set occupies, its records counted in full even when other sets share them (an
    /// upper bound, so caches that weigh by it stay under their budget).
    pub fn byte_size(&self) -> usize {
        let records: usize = self
            .records
            .iter()
            .map(|r| r.byte_size() + std::mem::size_of::<Arc<BuildingRecord>>())
            .sum();
        let clusters: usize = self
            .clusters
            .iter()
            .map(|c| {
                std::mem::size_of::<ClusterInfo>()
                    + c.records.capacity() * std::mem::size_of::<usize>()
            })
            .sum();
        let grid: usize = self
            .grid
            .values()
            .map(|v| 48 + v.capacity() * std::mem::size_of::<u32>())
            .sum();
        std::mem::size_of::<Self>() + records + clusters + grid
    }

    pub fn clusters(&self) -> &[ClusterInfo] {
        &self.clusters
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The records of a cluster.
    pub fn cluster_records(&self, c: &ClusterInfo) -> Vec<&BuildingRecord> {
        c.records
            .iter()
            .map(|&i| self.records[i].as_ref())
            .collect()
    }

    /// Every cluster's records, in cluster order: the input of [`crate::scene::Scene::new`].
    pub fn groups(&self) -> Vec<Vec<&BuildingRecord>> {
        self.clusters
            .iter()
            .map(|c| self.cluster_records(c))
            .collect()
    }

    /// The extent of all buildings, or `None` for an empty set.
    pub fn extent(&self) -> Option<GeoBbox> {
        let e = self
            .clusters
            .iter()
            .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |a, c| {
                let b = c.bounds;
                [
                    a[0].min(b[0]),
                    a[1].min(b[1]),
                    a[2].max(b[2]),
                    a[3].max(b[3]),
                ]
            });
        GeoBbox::new(e[0], e[1], e[2], e[3]).ok()
    }

    fn candidates(&self, bbox: &GeoBbox) -> Vec<u32> {
        let ((cx0, cy0), (cx1, cy1)) = (
            cell(bbox.min_lon(), bbox.min_lat()),
            cell(bbox.max_lon(), bbox.max_lat()),
        );
        let mut out: Vec<u32> = Vec::new();
        for cx in cx0..=cx1 {
            for cy in cy0..=cy1 {
                if let Some(list) = self.grid.get(&(cx, cy)) {
                    out.extend_from_slice(list);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Clusters with any part inside `bbox`, in a stable order.
    pub fn clusters_intersecting(&self, bbox: &GeoBbox) -> Vec<&ClusterInfo> {
        self.candidates(bbox)
            .into_iter()
            .map(|i| &self.clusters[i as usize])
            .filter(|c| {
                let [x0, y0, x1, y1] = c.bounds;
                x0 <= bbox.max_lon()
                    && x1 >= bbox.min_lon()
                    && y0 <= bbox.max_lat()
                    && y1 >= bbox.min_lat()
            })
            .collect()
    }

    /// Clusters whose representative point lies in the tile (each cluster is in exactly one
    /// tile of a zoom level).
    pub fn clusters_of_tile(&self, tile: &TileCoord) -> Vec<&ClusterInfo> {
        self.candidates(&tile.bounds())
            .into_iter()
            .map(|i| &self.clusters[i as usize])
            .filter(|c| c.xyz_tile(tile.z) == *tile)
            .collect()
    }

    /// Clusters that belong to a tile of the implicit quadtree over `root` (see
    /// [`ClusterInfo::implicit_tile`]).
    pub fn clusters_of_implicit_tile(
        &self,
        root: &GeoBbox,
        tile: &ImplicitTile,
    ) -> Vec<&ClusterInfo> {
        let Ok(bbox) = tile.bbox(root) else {
            return Vec::new();
        };
        self.clusters_intersecting(&bbox)
            .into_iter()
            .filter(|c| c.implicit_tile(root, tile.level) == Some(*tile))
            .collect()
    }

    /// The `(x, y)` of every tile at `level` of the tree over `root` that holds a cluster: the
    /// tiles with content.
    pub fn implicit_tiles_with_content(&self, root: &GeoBbox, level: u8) -> BTreeSet<(u32, u32)> {
        self.clusters_intersecting(root)
            .into_iter()
            .filter_map(|c| c.implicit_tile(root, level))
            .map(|t| (t.x, t.y))
            .collect()
    }
}

/// The smallest box holding `bbox` and every cluster's extent.
pub fn extent_with(bbox: &GeoBbox, clusters: &[&ClusterInfo]) -> GeoBbox {
    let mut e = [
        bbox.min_lon(),
        bbox.min_lat(),
        bbox.max_lon(),
        bbox.max_lat(),
    ];
    for c in clusters {
        e = [
            e[0].min(c.bounds[0]),
            e[1].min(c.bounds[1]),
            e[2].max(c.bounds[2]),
            e[3].max(c.bounds[3]),
        ];
    }
    GeoBbox::new(e[0], e[1], e[2], e[3]).unwrap_or(*bbox)
}

//! The ground of a coarse level of detail: a regular grid of `cells` x `cells` over the box,
//! each corner at the elevation model's height there (the same surface the full ground
//! follows, sampled sparsely), so a tile of any size costs the same few hundred triangles.

use super::ElevationModel;
use super::ground::GroundReport;
use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};

/// Which cells of a 16 x 16 grid hold ground: bit `row * 16 + column`, rows counted from the
/// south.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CellMask(pub [u64; 4]);

impl CellMask {
    /// Every cell.
    pub const ALL: CellMask = CellMask([u64::MAX; 4]);
    /// No cell.
    pub const NONE: CellMask = CellMask([0; 4]);

    /// Whether cell (`column`, `row` from the south) holds ground.
    pub fn contains(&self, column: u32, row: u32) -> bool {
        let bit = (row * 16 + column) as usize;
        bit < 256 && self.0[bit / 64] & (1 << (bit % 64)) != 0
    }

    /// Marks cell (`column`, `row` from the south).
    pub fn insert(&mut self, column: u32, row: u32) {
        let bit = (row * 16 + column) as usize;
        if bit < 256 {
            self.0[bit / 64] |= 1 << (bit % 64);
        }
    }
}

/// Adds a `cells` x `cells` grid of ground over `bbox` to `mesh` in `frame` (with a 16-cell
/// grid, only the cells `mask` holds).
pub fn build_coarse_ground(
    model: &ElevationModel,
    bbox: &GeoBbox,
    frame: &LocalFrame,
    cells: u32,
    mask: Option<&CellMask>,
    mesh: &mut Mesh,
) -> GroundReport {
    let n = cells.max(1);
    let mask = mask.filter(|_| n == 16);
    let (w, s) = (bbox.min_lon(), bbox.min_lat());
    let (dx, dy) = (
        (bbox.max_lon() - w) / f64::from(n),
        (bbox.max_lat() - s) / f64::from(n),
    );
    let mut corners: Vec<Option<u32>> = vec![None; ((n + 1) * (n + 1)) as usize];
    let mut at = |i: u32, j: u32, mesh: &mut Mesh| {
        *corners[(j * (n + 1) + i) as usize].get_or_insert_with(|| {
            // The last row and column sit exactly on the box's east and north sides.
            let lon = if i == n {
                bbox.max_lon()
            } else {
                w + dx * f64::from(i)
            };
            let lat = if j == n {
                bbox.max_lat()
            } else {
                s + dy * f64::from(j)
            };
            let at = mesh.positions.len() as u32;
            mesh.push_vertex(frame.to_local(lon, lat, model.ground_height(lon, lat)));
            at
        })
    };
    let style = FaceStyle::plain(Material::Ground, Rgb::GROUND);
    let mut drawn = 0;
    for j in 0..n {
        for i in 0..n {
            if mask.is_some_and(|m| !m.contains(i, j)) {
                continue;
            }
            let (a, b) = (at(i, j, mesh), at(i + 1, j, mesh));
            let (c, d) = (at(i + 1, j + 1, mesh), at(i, j + 1, mesh));
            // Counter-clockwise seen from above: east, then north.
            mesh.push_triangle([a, b, c], style);
            mesh.push_triangle([a, c, d], style);
            drawn += 1;
        }
    }
    GroundReport {
        cells: drawn,
        triangles: 2 * drawn,
        ..GroundReport::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::ElevationModel;

    #[test]
    fn a_grid_covers_the_box_with_two_triangles_a_cell_facing_up() {
        let model = ElevationModel::new(Vec::new());
        let bbox = GeoBbox::new(8.0, 49.0, 8.01, 49.01).unwrap();
        let (lon, lat) = bbox.center();
        let frame = LocalFrame::new(lon, lat, 0.0);
        let mut mesh = Mesh::default();
        let r = build_coarse_ground(&model, &bbox, &frame, 4, None, &mut mesh);
        assert_eq!(
            (mesh.positions.len(), mesh.triangles.len(), r.triangles),
            (25, 32, 32)
        );
        for t in &mesh.triangles {
            let [a, b, c] = mesh.corners(*t);
            assert!(crate::mesh::triangle_normal(a, b, c)[2] > 0.0);
        }
        // The corners are the box's corners.
        let (lon0, lat0, _) = frame.to_geographic(mesh.positions[0]);
        let (lon1, lat1, _) = frame.to_geographic(mesh.positions[24]);
        assert!((lon0 - 8.0).abs() < 1e-9 && (lat0 - 49.0).abs() < 1e-9);
        assert!((lon1 - 8.01).abs() < 1e-9 && (lat1 - 49.01).abs() < 1e-9);
    }
}

//! The ground mesh of a bounding box (docs/method.md section 1).
//!
//! Every valid sample is the centre of a cell; the cell's corners average the valid cells around
//! them; each cell becomes four triangles (corner, corner, centre). Void cells stay empty. Cells
//! that straddle the bounding box are clipped to it, and the new border vertices take their height
//! from Equation 1, so two boxes that share an edge (neighbouring tiles) produce the very same
//! border vertices.

use super::elevation::{corner_height, equation_1};
use super::model::{ElevationModel, Sample};
use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};
use foldhash::HashMap;

/// What the ground of one bounding box is made of.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GroundReport {
    /// Cells that overlap the box.
    pub cells: usize,
    /// Of those, cells left empty because their sample is void.
    pub void_cells: usize,
    /// Samples that no DEM file covers, taken as the 0 m fallback plane.
    pub missing_samples: usize,
    /// Triangles added to the mesh.
    pub triangles: usize,
}

/// A rectangular window of samples with one ring of extra cells around the cells in use.
struct Window {
    i0: i64,
    j0: i64,
    width: usize,
    samples: Vec<Option<f64>>,
}

impl Window {
    #[inline]
    fn get(&self, i: i64, j: i64) -> Option<f64> {
        self.samples[(j - self.j0) as usize * self.width + (i - self.i0) as usize]
    }

    /// The cell of `u` (sample units) and the offset in it, kept to the cells in use: a point
    /// exactly on the box's outer edge belongs to the last cell inside (Equation 1 gives both
    /// cells the same height along their shared edge), so its corners stay in the window.
    fn cell_of(&self, u: f64, first: i64, count: usize) -> (i64, f64) {
        let (i, _) = super::elevation::cell_of(u);
        let i = i.clamp(first + 1, first + count as i64 - 2);
        (i, (u - i as f64).clamp(-0.5, 0.5))
    }
}

/// A vertex of a clipped polygon, in sample units.
#[derive(Clone, Copy)]
struct ClipVertex {
    u: f64,
    v: f64,
    /// The mesh vertex, when this is one of the triangle's own corners.
    id: Option<u32>,
    /// Bit set of the box lines the vertex lies on (1 = west, 2 = east, 4 = south, 8 = north).
    on: u8,
}

/// Adds the ground of `bbox` to `mesh` in `frame`.
pub fn build_ground(
    model: &ElevationModel,
    bbox: &GeoBbox,
    frame: &LocalFrame,
    mesh: &mut Mesh,
) -> GroundReport {
    let p = f64::from(model.per_degree());
    let (umin, umax) = (bbox.min_lon() * p, bbox.max_lon() * p);
    let (vmin, vmax) = (bbox.min_lat() * p, bbox.max_lat() * p);
    // Cells [i - 0.5, i + 0.5] that overlap the box with some area.
    let (ci0, ci1) = (
        (umin - 0.5).floor() as i64 + 1,
        (umax + 0.5).ceil() as i64 - 1,
    );
    let (cj0, cj1) = (
        (vmin - 0.5).floor() as i64 + 1,
        (vmax + 0.5).ceil() as i64 - 1,
    );

    let mut report = GroundReport::default();
    let width = (ci1 - ci0 + 3) as usize;
    let height = (cj1 - cj0 + 3) as usize;
    let mut samples = Vec::with_capacity(width * height);
    for j in cj0 - 1..=cj1 + 1 {
        for i in ci0 - 1..=ci1 + 1 {
            samples.push(match model.sample(i, j) {
                Sample::Valid(h) => Some(h),
                Sample::Void => None,
                Sample::Missing => {
                    report.missing_samples += 1;
                    Some(0.0)
                }
            });
        }
    }
    let window = Window {
        i0: ci0 - 1,
        j0: cj0 - 1,
        width,
        samples,
    };

    // Corner (ci, cj) sits at (ci + 0.5, cj + 0.5); it is created on first use.
    let corner_w = (ci1 - ci0 + 2) as usize;
    let mut corner_ids = vec![u32::MAX; corner_w * (cj1 - cj0 + 2) as usize];
    let mut border_ids: HashMap<(u64, u64), u32> = HashMap::default();
    let style = FaceStyle::plain(Material::Ground, Rgb::GROUND);
    let first_triangle = mesh.triangles.len();
    let to_local = |u: f64, v: f64, h: f64| frame.to_local(u / p, v / p, h);

    for j in cj0..=cj1 {
        for i in ci0..=ci1 {
            report.cells += 1;
            let Some(c) = window.get(i, j) else {
                report.void_cells += 1;
                continue;
            };
            let (fu, fv) = (i as f64, j as f64);
            // Corners in order SW, SE, NE, NW: grid index and position.
            let corner_at = [(i - 1, j - 1), (i, j - 1), (i, j), (i - 1, j)];
            let corner_pos = [
                (fu - 0.5, fv - 0.5),
                (fu + 0.5, fv - 0.5),
                (fu + 0.5, fv + 0.5),
                (fu - 0.5, fv + 0.5),
            ];
            let mut ids = [0u32; 4];
            let inside =
                fu - 0.5 >= umin && fu + 0.5 <= umax && fv - 0.5 >= vmin && fv + 0.5 <= vmax;
            for k in 0..4 {
                let (ci, cj) = corner_at[k];
                let h = corner_height([
                    window.get(ci, cj),
                    window.get(ci + 1, cj),
                    window.get(ci, cj + 1),
                    window.get(ci + 1, cj + 1),
                ])
                // The cell itself is one of the four and valid, so the mean always exists.
                .unwrap_or(c);
                let (u, v) = corner_pos[k];
                // Corners outside the box are only referenced after clipping removes them.
                if u < umin || u > umax || v < vmin || v > vmax {
                    ids[k] = u32::MAX;
                    continue;
                }
                let slot = &mut corner_ids
                    [(cj - (cj0 - 1)) as usize * corner_w + (ci - (ci0 - 1)) as usize];
                if *slot == u32::MAX {
                    *slot = mesh.push_vertex(to_local(u, v, h));
                }
                ids[k] = *slot;
            }
            let centre_inside = (umin..=umax).contains(&fu) && (vmin..=vmax).contains(&fv);
            let centre = if centre_inside {
                mesh.push_vertex(to_local(fu, fv, c))
            } else {
                u32::MAX
            };

            for k in 0..4 {
                let (a, b) = (k, (k + 1) % 4);
                if inside {
                    mesh.push_triangle([ids[a], ids[b], centre], style);
                    continue;
                }
                let tri = [
                    ClipVertex {
                        u: corner_pos[a].0,
                        v: corner_pos[a].1,
                        id: Some(ids[a]),
                        on: 0,
                    },
                    ClipVertex {
                        u: corner_pos[b].0,
                        v: corner_pos[b].1,
                        id: Some(ids[b]),
                        on: 0,
                    },
                    ClipVertex {
                        u: fu,
                        v: fv,
                        id: Some(centre),
                        on: 0,
                    },
                ];
                let polygon = clip_to_box(&tri, [umin, umax, vmin, vmax]);
                if polygon.len() < 3 {
                    continue;
                }
                let mut poly_ids = Vec::with_capacity(polygon.len());
                for cv in &polygon {
                    let id = match cv.id {
                        Some(id) => id,
                        None => {
                            let (u, v) = canonical_border_point(cv, &tri, [umin, umax, vmin, vmax]);
                            *border_ids
                                .entry((u.to_bits(), v.to_bits()))
                                .or_insert_with(|| {
                                    let h = model_height(&window, u, v);
                                    mesh.push_vertex(to_local(u, v, h))
                                })
                        }
                    };
                    if poly_ids.last() != Some(&id) && poly_ids.first() != Some(&id) {
                        poly_ids.push(id);
                    }
                }
                for k in 1..poly_ids.len().saturating_sub(1) {
                    let t = [poly_ids[0], poly_ids[k], poly_ids[k + 1]];
                    if has_area(mesh, t) {
                        mesh.push_triangle(t, style);
                    }
                }
            }
        }
    }
    report.triangles = mesh.triangles.len() - first_triangle;
    report
}

/// Equation 1 over the window's samples.
fn model_height(window: &Window, u: f64, v: f64) -> f64 {
    let rows = window.samples.len() / window.width;
    let (i, du) = window.cell_of(u, window.i0, window.width);
    let (j, dv) = window.cell_of(v, window.j0, rows);
    let corner = |ci: i64, cj: i64| {
        corner_height([
            window.get(ci, cj),
            window.get(ci + 1, cj),
            window.get(ci, cj + 1),
            window.get(ci + 1, cj + 1),
        ])
        .unwrap_or(0.0)
    };
    let c = window.get(i, j).unwrap_or(0.0);
    equation_1(
        c,
        [
            corner(i - 1, j - 1),
            corner(i, j - 1),
            corner(i, j),
            corner(i - 1, j),
        ],
        du,
        dv,
    )
}

fn has_area(mesh: &Mesh, t: [u32; 3]) -> bool {
    let [a, b, c] = mesh.corners(t);
    let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    cross > 1e-9
}

/// Sutherland-Hodgman clipping of a convex polygon to the box `[umin, umax, vmin, vmax]`. New
/// vertices get the clipping line's coordinate exactly.
fn clip_to_box(polygon: &[ClipVertex], [umin, umax, vmin, vmax]: [f64; 4]) -> Vec<ClipVertex> {
    let mut current: Vec<ClipVertex> = polygon.to_vec();
    // (is the line vertical, its value, keep the side >= value, bit)
    let lines = [
        (true, umin, true, 1u8),
        (true, umax, false, 2),
        (false, vmin, true, 4),
        (false, vmax, false, 8),
    ];
    for (vertical, value, keep_above, bit) in lines {
        if current.is_empty() {
            break;
        }
        let coord = |c: &ClipVertex| if vertical { c.u } else { c.v };
        let inside = |c: &ClipVertex| {
            if keep_above {
                coord(c) >= value
            } else {
                coord(c) <= value
            }
        };
        let mut next = Vec::with_capacity(current.len() + 2);
        for k in 0..current.len() {
            let a = current[k];
            let b = current[(k + 1) % current.len()];
            let (ia, ib) = (inside(&a), inside(&b));
            if ia {
                let mut a = a;
                if coord(&a) == value {
                    a.on |= bit;
                }
                next.push(a);
            }
            // A crossing at an endpoint that lies on the line would repeat that endpoint.
            if ia != ib && coord(&a) != value && coord(&b) != value {
                next.push(cross_line(a, b, vertical, value, bit));
            }
        }
        current = next;
    }
    current
}

/// Where segment a-b crosses a box line, computed from the endpoints in a fixed order so the same
/// segment gives the same bits whichever way it is walked.
fn cross_line(a: ClipVertex, b: ClipVertex, vertical: bool, value: f64, bit: u8) -> ClipVertex {
    let (p, q) = if (a.u, a.v) <= (b.u, b.v) {
        (a, b)
    } else {
        (b, a)
    };
    let (u, v) = if vertical {
        (value, p.v + (value - p.u) * (q.v - p.v) / (q.u - p.u))
    } else {
        (p.u + (value - p.v) * (q.u - p.u) / (q.v - p.v), value)
    };
    ClipVertex {
        u,
        v,
        id: None,
        on: (a.on & b.on) | bit,
    }
}

/// A clipped vertex recomputed from the original triangle edge it lies on (or as the box corner),
/// so neighbouring cells and neighbouring boxes get identical coordinates.
fn canonical_border_point(
    cv: &ClipVertex,
    tri: &[ClipVertex; 3],
    [umin, umax, vmin, vmax]: [f64; 4],
) -> (f64, f64) {
    let u_line = if cv.on & 1 != 0 {
        Some(umin)
    } else if cv.on & 2 != 0 {
        Some(umax)
    } else {
        None
    };
    let v_line = if cv.on & 4 != 0 {
        Some(vmin)
    } else if cv.on & 8 != 0 {
        Some(vmax)
    } else {
        None
    };
    match (u_line, v_line) {
        (Some(u), Some(v)) => (u, v),
        (Some(u), None) => {
            let v = best_crossing(tri, true, u, cv.v);
            (u, v)
        }
        (None, Some(v)) => {
            let u = best_crossing(tri, false, v, cv.u);
            (u, v)
        }
        (None, None) => (cv.u, cv.v),
    }
}

/// The crossing of a triangle edge with a box line that lies nearest to `near`.
fn best_crossing(tri: &[ClipVertex; 3], vertical: bool, value: f64, near: f64) -> f64 {
    let mut best = near;
    let mut best_d = f64::INFINITY;
    for k in 0..3 {
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        let (ca, cb) = if vertical { (a.u, b.u) } else { (a.v, b.v) };
        if ca == cb || value < ca.min(cb) || value > ca.max(cb) {
            continue;
        }
        let c = cross_line(a, b, vertical, value, 0);
        let other = if vertical { c.v } else { c.u };
        let d = (other - near).abs();
        if d < best_d {
            best_d = d;
            best = other;
        }
    }
    best
}

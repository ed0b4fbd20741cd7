//! Wall pieces: vertical quadrilaterals over one stretch of a footprint edge, between a bottom and
//! a top height at each end, with extra points on their vertical sides where neighbouring pieces
//! end (so every edge is shared by exactly two triangles).
use super::length::planar_length;

use crate::mesh::{FaceStyle, Mesh};

/// One end of a wall piece: its position, bottom and top height, and the heights at which other
/// pieces meeting on this vertical line end (any order; those outside (bottom, top) are ignored).
#[derive(Debug, Clone, Copy)]
pub struct WallEnd<'a> {
    pub at: [f64; 2],
    pub bottom: f64,
    pub top: f64,
    pub splits: &'a [f64],
}

/// Heights closer than this (metres) are one: wall pieces never get slivers thinner than this.
pub const SAME_HEIGHT: f64 = 1e-6;

/// Adds the wall piece from `u` to `v` (the outside is on the right of `u` -> `v`), counter-clockwise
/// seen from outside.
pub fn push_wall_piece(mesh: &mut Mesh, u: WallEnd, v: WallEnd, style: FaceStyle) {
    // (distance along the wall, height) for the planar test, and 3D points.
    let len = planar_length(v.at[0] - u.at[0], v.at[1] - u.at[1]);
    let mut poly: Vec<(f64, f64, [f64; 3])> = Vec::with_capacity(8);
    let mut push = |w: f64, z: f64, at: [f64; 2]| {
        if let Some(last) = poly.last()
            && last.0 == w
            && (last.1 - z).abs() <= SAME_HEIGHT
        {
            return;
        }
        poly.push((w, z, [at[0], at[1], z]));
    };
    push(0.0, u.bottom, u.at);
    push(len, v.bottom, v.at);
    let mut up: Vec<f64> = v
        .splits
        .iter()
        .copied()
        .filter(|&z| z > v.bottom + SAME_HEIGHT && z < v.top - SAME_HEIGHT)
        .collect();
    up.sort_by(f64::total_cmp);
    for z in up {
        push(len, z, v.at);
    }
    push(len, v.top, v.at);
    push(0.0, u.top, u.at);
    let mut down: Vec<f64> = u
        .splits
        .iter()
        .copied()
        .filter(|&z| z > u.bottom + SAME_HEIGHT && z < u.top - SAME_HEIGHT)
        .collect();
    down.sort_by(|a, b| b.total_cmp(a));
    for z in down {
        push(0.0, z, u.at);
    }
    if poly.len() > 1 {
        let (first, last) = (poly[0], poly[poly.len() - 1]);
        if first.0 == last.0 && (first.1 - last.1).abs() <= SAME_HEIGHT {
            poly.pop();
        }
    }
    push_convex(mesh, &poly, style);
}

/// Triangulates a convex planar polygon given as (w, z, point) without degenerate triangles: a fan
/// from the first corner when no three consecutive points are collinear, else from its centre.
fn push_convex(mesh: &mut Mesh, poly: &[(f64, f64, [f64; 3])], style: FaceStyle) {
    let n = poly.len();
    if n < 3 {
        return;
    }
    let area2: f64 = (0..n)
        .map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            p.0 * q.1 - q.0 * p.1
        })
        .sum();
    if area2.abs() <= 1e-12 {
        return;
    }
    let straight = (0..n).any(|i| {
        let (a, b, c) = (poly[(i + n - 1) % n], poly[i], poly[(i + 1) % n]);
        let o = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        o.abs() <= 1e-12 * (1.0 + (b.0 - a.0).abs() + (c.1 - a.1).abs()).powi(2)
    });
    let first = mesh.positions.len() as u32;
    for p in poly {
        mesh.push_vertex(p.2);
    }
    if !straight {
        for i in 1..n as u32 - 1 {
            mesh.push_triangle([first, first + i, first + i + 1], style);
        }
        return;
    }
    let c = poly.iter().fold([0.0; 3], |s, p| {
        [
            s[0] + p.2[0] / n as f64,
            s[1] + p.2[1] / n as f64,
            s[2] + p.2[2] / n as f64,
        ]
    });
    let centre = mesh.push_vertex(c);
    for i in 0..n as u32 {
        mesh.push_triangle([centre, first + i, first + (i + 1) % n as u32], style);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Material, Rgb};

    const STYLE: FaceStyle = FaceStyle::plain(Material::Wall, Rgb(1, 2, 3));

    fn end(at: [f64; 2], bottom: f64, top: f64, splits: &[f64]) -> WallEnd<'_> {
        WallEnd {
            at,
            bottom,
            top,
            splits,
        }
    }

    #[test]
    fn a_plain_wall_is_two_triangles_facing_out() {
        let mut m = Mesh::default();
        push_wall_piece(
            &mut m,
            end([0.0, 0.0], 0.0, 3.0, &[]),
            end([4.0, 0.0], 0.0, 5.0, &[]),
            STYLE,
        );
        assert_eq!(m.triangles.len(), 2);
        // Outside is to the right of east-going u -> v: the south, so normals point to -y.
        for t in &m.triangles {
            let [a, b, c] = m.corners(*t);
            let (u, w) = (
                [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
            );
            let ny = u[2] * w[0] - u[0] * w[2];
            assert!(ny < 0.0);
        }
    }

    #[test]
    fn splits_on_the_sides_fan_from_the_centre() {
        let mut m = Mesh::default();
        push_wall_piece(
            &mut m,
            end([0.0, 0.0], 0.0, 6.0, &[2.0, 9.0]),
            end([4.0, 0.0], 0.0, 6.0, &[3.0, 0.0]),
            STYLE,
        );
        // Six corners (two splits kept) around a centre: six triangles.
        assert_eq!(m.triangles.len(), 6);
        assert_eq!(m.positions.len(), 7);
    }

    #[test]
    fn a_piece_that_closes_to_a_point_is_a_triangle() {
        let mut m = Mesh::default();
        push_wall_piece(
            &mut m,
            end([0.0, 0.0], 5.0, 5.0, &[]),
            end([4.0, 0.0], 3.0, 7.0, &[]),
            STYLE,
        );
        assert_eq!(m.triangles.len(), 1);
    }
}

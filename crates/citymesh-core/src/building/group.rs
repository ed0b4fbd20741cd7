//! Meshing a group of volumes that touch (docs/method.md section 7): buildings that share OSM
//! nodes, and an outline with its parts. Walls hidden between two volumes along a shared edge are
//! left out up to the lower of the two, so the group's surface has no inner faces and stays
//! closed: along a shared edge, each volume only shows the strip below the other's floor and the
//! part of its wall above the other's roof.
//!
//! To keep every edge shared by exactly two triangles, both volumes put the same points on a
//! shared edge (the union of the points where either roof bends there, plus where the two roofs
//! cross or pass the other's floor, so that between two points one rule holds), and every vertical wall side at a node is split at the floor and roof heights of all
//! volumes meeting at that node.

use super::boundary::{
    End, canonical, divide, edge_key, edge_length, edge_point, insert_split, insert_split_within,
};
use super::footprint::{Footprint, MERGE_DISTANCE, NodeKey};
use super::roof_surface::RoofSurface;
use super::triangulate::triangulate;
use super::walls::{SAME_HEIGHT, WallEnd, push_wall_piece};
use crate::mesh::{FaceStyle, Material, Mesh, Rgb};
use foldhash::HashMap;
use std::borrow::Cow;

/// One closed volume: a footprint piece, the roof over it and the floor height.
#[derive(Debug, Clone)]
pub struct Volume<'f> {
    /// The piece: borrowed when it is a whole outline, owned when parts or the scene border cut it.
    pub footprint: Cow<'f, Footprint>,
    /// Index of the roof in the group's roof list (pieces of one building share a roof).
    pub roof: usize,
    /// Height of the floor, metres in the local frame.
    pub floor: f64,
    pub wall_colour: Rgb,
    pub roof_colour: Rgb,
    /// The building the volume belongs to (its row in the scene's feature list).
    pub feature: u32,
}

/// The floor colour (floors face the ground and are rarely seen).
const FLOOR_COLOUR: Rgb = Rgb(0x60, 0x60, 0x60);

/// What meshing a group met.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GroupReport {
    /// Edges shared by two volumes whose hidden walls were left out.
    pub shared_edges: usize,
    /// Dividing segments that crossed another constraint and were dropped.
    pub dropped_constraints: usize,
}

/// An edge of a volume: (volume, ring, edge).
type EdgeRef = (usize, usize, usize);

/// A shared edge as seen from one side: the other volume.
#[derive(Debug, Clone, Copy)]
struct Partner {
    volume: usize,
}

/// Adds the volumes of one group to the mesh.
pub fn mesh_group(volumes: &[Volume<'_>], roofs: &[RoofSurface], mesh: &mut Mesh) -> GroupReport {
    let mut report = GroupReport::default();
    let segments: Vec<_> = roofs.iter().map(RoofSurface::dividing_segments).collect();
    let mut divisions: Vec<_> = volumes
        .iter()
        .map(|v| divide(&v.footprint, &segments[v.roof]))
        .collect();

    // Edges that appear in two volumes, in opposite directions.
    let mut by_key: HashMap<(NodeKey, NodeKey), Vec<EdgeRef>> = HashMap::default();
    if volumes.len() > 1 {
        for (vi, v) in volumes.iter().enumerate() {
            for (r, ring) in v.footprint.rings().enumerate() {
                for e in 0..ring.len() {
                    let next = (e + 1) % ring.len();
                    by_key
                        .entry(edge_key(ring.keys[e], ring.keys[next]))
                        .or_default()
                        .push((vi, r, e));
                }
            }
        }
        by_key.retain(|_, sides| {
            sides.len() == 2 && sides[0].0 != sides[1].0 && {
                let key = |&(v, r, e): &(usize, usize, usize)| {
                    let ring = ring_of(&volumes[v].footprint, r);
                    ring.keys[e]
                };
                key(&sides[0]) != key(&sides[1])
            }
        });
    }

    // Shared edges: the same points on both sides, where the roofs cross too; hidden walls go
    // only where both walls stand over the whole edge.
    let mut partner: HashMap<(usize, usize, usize), Partner> = HashMap::default();
    for sides in by_key.values() {
        let [(va, ra, ea), (vb, rb, eb)] = [sides[0], sides[1]];
        let ring_a = ring_of(&volumes[va].footprint, ra);
        let len = edge_length(ring_a, ea);
        let mut union = divisions[va].splits[ra][ea].clone();
        for &s in &divisions[vb].splits[rb][eb] {
            insert_split(&mut union, s, len);
        }
        let (roof_a, roof_b) = (&roofs[volumes[va].roof], &roofs[volumes[vb].roof]);
        let (floor_a, floor_b) = (volumes[va].floor, volumes[vb].floor);
        // Where the two roofs cross, and where either roof passes the other's floor: between
        // these points, which wall hides which stays the same.
        let differences: [&dyn Fn([f64; 2]) -> f64; 3] = [
            &|p| roof_a.height_at(p) - roof_b.height_at(p),
            &|p| roof_a.height_at(p) - floor_b,
            &|p| roof_b.height_at(p) - floor_a,
        ];
        for diff in differences {
            let stops: Vec<f64> = std::iter::once(0.0)
                .chain(union.iter().copied())
                .chain(std::iter::once(1.0))
                .collect();
            let mut crossings = Vec::new();
            for w in stops.windows(2) {
                let d0 = diff(edge_point(ring_a, ea, w[0]));
                let d1 = diff(edge_point(ring_a, ea, w[1]));
                if (d0 > SAME_HEIGHT && d1 < -SAME_HEIGHT)
                    || (d0 < -SAME_HEIGHT && d1 > SAME_HEIGHT)
                {
                    crossings.push(w[0] + (w[1] - w[0]) * d0 / (d0 - d1));
                }
            }
            // Crossings go in however close to another point: skipping one would leave the
            // two walls disagreeing by its slope over that distance.
            for s in crossings {
                insert_split_within(&mut union, s, len, SAME_HEIGHT);
            }
        }
        divisions[vb].splits[rb][eb] = union.clone();
        divisions[va].splits[ra][ea] = union;
        report.shared_edges += 1;
        partner.insert((va, ra, ea), Partner { volume: vb });
        partner.insert((vb, rb, eb), Partner { volume: va });
    }

    // Heights at which vertical wall sides end, per node.
    let mut node_heights: HashMap<NodeKey, Vec<f64>> = HashMap::default();
    if !partner.is_empty() {
        for v in volumes {
            let roof = &roofs[v.roof];
            for ring in v.footprint.rings() {
                for (p, k) in ring.points.iter().zip(&ring.keys) {
                    let h = node_heights.entry(*k).or_default();
                    h.push(v.floor);
                    h.push(roof.height_at(*p));
                }
            }
        }
    }

    for (vi, v) in volumes.iter().enumerate() {
        let roof = &roofs[v.roof];
        report.dropped_constraints += mesh_volume(
            vi,
            v,
            roof,
            &divisions[vi],
            &partner,
            volumes,
            roofs,
            &node_heights,
            mesh,
        );
    }
    report
}

fn ring_of(f: &Footprint, r: usize) -> &super::footprint::FootprintRing {
    if r == 0 { &f.outer } else { &f.holes[r - 1] }
}

/// One point of a ring with its extra points: where it is and, for original nodes, which.
#[derive(Clone, Copy)]
struct RingPoint {
    at: [f64; 2],
    node: Option<NodeKey>,
    /// The original edge this point starts a stretch of.
    edge: usize,
}

#[allow(clippy::too_many_arguments)]
fn mesh_volume(
    vi: usize,
    v: &Volume<'_>,
    roof: &RoofSurface,
    div: &super::boundary::Divisions,
    partner: &HashMap<(usize, usize, usize), Partner>,
    volumes: &[Volume<'_>],
    roofs: &[RoofSurface],
    node_heights: &HashMap<NodeKey, Vec<f64>>,
    mesh: &mut Mesh,
) -> usize {
    // The boundary with its extra points, ring after ring.
    let mut points: Vec<[f64; 2]> = Vec::new();
    let mut ring_points: Vec<Vec<RingPoint>> = Vec::new();
    let mut ranges = Vec::new();
    let mut node_index: Vec<Vec<usize>> = Vec::new();
    for (r, ring) in v.footprint.rings().enumerate() {
        let start = points.len();
        let mut rp = Vec::with_capacity(ring.len());
        let mut nodes = Vec::with_capacity(ring.len());
        for e in 0..ring.len() {
            nodes.push(points.len());
            points.push(ring.points[e]);
            rp.push(RingPoint {
                at: ring.points[e],
                node: Some(ring.keys[e]),
                edge: e,
            });
            let splits = &div.splits[r][e];
            let forward = canonical(ring, e).0 == e;
            let mut push = |s: f64| {
                let at = edge_point(ring, e, s);
                points.push(at);
                rp.push(RingPoint {
                    at,
                    node: None,
                    edge: e,
                });
            };
            if forward {
                splits.iter().for_each(|&s| push(s));
            } else {
                splits.iter().rev().for_each(|&s| push(s));
            }
        }
        ranges.push(start..points.len());
        ring_points.push(rp);
        node_index.push(nodes);
    }

    // Constraints from the dividing segments.
    let mut constraints = Vec::with_capacity(div.constraints.len());
    let resolve = |end: End, points: &mut Vec<[f64; 2]>| -> usize {
        match end {
            End::Node { ring, index } => node_index[ring][index],
            End::Edge { ring, edge, sigma } => {
                // The nearest extra point on that edge (shared edges may have merged it).
                let splits = &div.splits[ring][edge];
                let k = splits
                    .iter()
                    .enumerate()
                    .min_by(|a, b| (a.1 - sigma).abs().total_cmp(&(b.1 - sigma).abs()))
                    .map(|(k, _)| k);
                let r = ring_of(&v.footprint, ring);
                let forward = canonical(r, edge).0 == edge;
                match k {
                    Some(k) => {
                        let offset = if forward { k + 1 } else { splits.len() - k };
                        node_index[ring][edge] + offset
                    }
                    None => node_index[ring][edge],
                }
            }
            End::Interior(p) => {
                // One point for ends closer than the merge distance (rounding leaves the same
                // corner of two dividing segments a few ulps apart).
                let near = |q: &[f64; 2]| {
                    (q[0] - p[0]).abs() <= MERGE_DISTANCE && (q[1] - p[1]).abs() <= MERGE_DISTANCE
                };
                if let Some(i) = points.iter().position(near) {
                    return i;
                }
                points.push(p);
                points.len() - 1
            }
        }
    };
    for &[a, b] in &div.constraints {
        let (a, b) = (resolve(a, &mut points), resolve(b, &mut points));
        if a != b {
            constraints.push([a, b]);
        }
    }

    let on_edge: Vec<bool> = ring_points
        .iter()
        .flatten()
        .map(|p| p.node.is_none())
        .collect();
    let planar = triangulate(&v.footprint, points, &ranges, &constraints, &on_edge);
    let roof_style = FaceStyle {
        material: Material::Roof,
        colour: v.roof_colour,
        feature: v.feature,
    };
    let floor_style = FaceStyle {
        material: Material::Floor,
        colour: FLOOR_COLOUR,
        feature: v.feature,
    };
    let wall_style = FaceStyle {
        material: Material::Wall,
        colour: v.wall_colour,
        feature: v.feature,
    };
    let base = mesh.positions.len() as u32;
    for p in &planar.points {
        mesh.push_vertex([p[0], p[1], roof.height_at(*p)]);
    }
    let floor_base = mesh.positions.len() as u32;
    for p in &planar.points {
        mesh.push_vertex([p[0], p[1], v.floor]);
    }
    for t in &planar.triangles {
        mesh.push_triangle(t.map(|i| base + i), roof_style);
        mesh.push_triangle([t[0], t[2], t[1]].map(|i| floor_base + i), floor_style);
    }

    // Walls, stretch by stretch.
    let none: &[f64] = &[];
    for (r, rp) in ring_points.iter().enumerate() {
        let n = rp.len();
        for i in 0..n {
            let (a, b) = (rp[i], rp[(i + 1) % n]);
            let splits = |p: &RingPoint| {
                p.node
                    .and_then(|k| node_heights.get(&k))
                    .map_or(none, Vec::as_slice)
            };
            let (ta, tb) = (roof.height_at(a.at), roof.height_at(b.at));
            let end = |p: &RingPoint, bottom: f64, top: f64| WallEnd {
                at: p.at,
                bottom,
                top,
                splits: splits(p),
            };
            match partner.get(&(vi, r, a.edge)).map(|p| &volumes[p.volume]) {
                None => {
                    push_wall_piece(mesh, end(&a, v.floor, ta), end(&b, v.floor, tb), wall_style);
                }
                Some(o) => {
                    // Both walls stand between their floor and roof; the part both cover,
                    // [low, high] at each end, is hidden. This one shows what is below the
                    // other's floor and what is above the hidden part.
                    let oroof = &roofs[o.roof];
                    let low = v.floor.max(o.floor);
                    let high = |at: [f64; 2], t: f64| low.max(t.min(oroof.height_at(at)));
                    let (high_a, high_b) = (high(a.at, ta), high(b.at, tb));
                    if v.floor < o.floor - SAME_HEIGHT {
                        push_wall_piece(
                            mesh,
                            end(&a, v.floor, low.min(ta)),
                            end(&b, v.floor, low.min(tb)),
                            wall_style,
                        );
                    }
                    let (base_a, base_b) =
                        (high_a.max(v.floor).min(ta), high_b.max(v.floor).min(tb));
                    if ta > base_a + SAME_HEIGHT || tb > base_b + SAME_HEIGHT {
                        push_wall_piece(mesh, end(&a, base_a, ta), end(&b, base_b, tb), wall_style);
                    }
                }
            }
        }
    }
    planar.dropped_constraints
}

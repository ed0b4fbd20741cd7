//! The wavefront of a straight skeleton, simulated event by event (see the parent module).

use super::faces::chain_face;
use super::planar_length;
use super::vector::{add, cross, dist, dot, scale, sub};
use super::{Arc, EdgeLine, Skeleton, SkeletonError, SkeletonNode};

/// Edges whose inward normals are closer than this to opposite (`1 + n1.n2`) are taken as
/// parallel and facing: their wavefronts meet along their whole common stretch.
const FACING: f64 = 1e-12;

/// Lengths (m) below which two points of the wavefront are one.
const SAME_POINT: f64 = 1e-7;

/// A vertex of the moving wavefront: where it was at `t0`, how it moves, and the edges before
/// and after it.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    origin: [f64; 2],
    t0: f64,
    vel: [f64; 2],
    /// The edge arriving at this vertex and the one leaving it.
    left: usize,
    right: usize,
    /// The node it set out from.
    node: usize,
}

impl Vertex {
    #[inline]
    fn at(&self, t: f64) -> [f64; 2] {
        add(self.origin, scale(self.vel, t - self.t0))
    }
}

/// What can happen next.
#[derive(Debug, Clone, Copy)]
enum Event {
    /// The edge after vertex `i` of loop `l` shrinks to nothing.
    Edge { l: usize, i: usize },
    /// Reflex vertex `i` of loop `l` runs into the edge after vertex `j` of loop `m`.
    Split {
        l: usize,
        i: usize,
        m: usize,
        j: usize,
    },
}

/// The moving wavefront: its loops of vertices, and the nodes and arcs it has left behind.
#[derive(Default)]
pub(super) struct Wavefront {
    edges: Vec<EdgeLine>,
    nodes: Vec<SkeletonNode>,
    loops: Vec<Vec<Vertex>>,
    arcs: Vec<Arc>,
    /// The input point each edge ends at (its start is the point of its own index).
    edge_ends: Vec<usize>,
    time: f64,
}

impl Wavefront {
    /// The wavefront at time 0 of `rings`, moved by `-origin`: one loop per ring, a node per
    /// point.
    pub(super) fn start(rings: &[&[[f64; 2]]], origin: [f64; 2]) -> Result<Self, SkeletonError> {
        let mut wave = Wavefront::default();
        let mut first_edge = 0;
        for ring in rings {
            let n = ring.len();
            for i in 0..n {
                let a = sub(ring[i], origin);
                let b = sub(ring[(i + 1) % n], origin);
                wave.edges.push(EdgeLine::new(a, b));
                wave.nodes.push(SkeletonNode { at: a, time: 0.0 });
            }
            for i in 0..n {
                wave.edge_ends.push(first_edge + (i + 1) % n);
            }
            let mut ring_loop = Vec::with_capacity(n);
            for i in 0..n {
                let (left, right) = (first_edge + (i + n - 1) % n, first_edge + i);
                let vel = wave.velocity(left, right).ok_or(SkeletonError::Spike)?;
                ring_loop.push(Vertex {
                    origin: wave.nodes[first_edge + i].at,
                    t0: 0.0,
                    vel,
                    left,
                    right,
                    node: first_edge + i,
                });
            }
            wave.loops.push(ring_loop);
            first_edge += n;
        }
        Ok(wave)
    }

    /// The velocity of a vertex between edges `left` and `right`: along their bisector, fast
    /// enough to stay on both moving lines. `None` when the edges face each other.
    fn velocity(&self, left: usize, right: usize) -> Option<[f64; 2]> {
        let (n1, n2) = (self.edges[left].n, self.edges[right].n);
        let d = 1.0 + dot(n1, n2);
        (d > FACING).then(|| scale(add(n1, n2), 1.0 / d))
    }

    fn is_reflex(&self, v: &Vertex) -> bool {
        cross(self.edges[v.left].u, self.edges[v.right].u) < -1e-12
    }

    fn node(&mut self, at: [f64; 2]) -> usize {
        self.nodes.push(SkeletonNode {
            at,
            time: self.time,
        });
        self.nodes.len() - 1
    }

    /// The vertex `v` stops at `node`: its path is an arc between its two faces.
    fn end(&mut self, v: &Vertex, node: usize) {
        self.arcs.push(Arc {
            nodes: [v.node, node],
            faces: [v.left, v.right],
        });
    }

    /// A new vertex at `node` between `left` and `right` (standing still when they face each
    /// other: [`Wavefront::settle`] lays their ridge).
    fn vertex(&self, node: usize, left: usize, right: usize) -> Vertex {
        Vertex {
            origin: self.nodes[node].at,
            t0: self.time,
            vel: self.velocity(left, right).unwrap_or([0.0, 0.0]),
            left,
            right,
            node,
        }
    }

    pub(super) fn run(&mut self, vertices: usize) -> Result<(), SkeletonError> {
        // Each event removes a vertex or splits a loop; a generous bound catches a wavefront
        // that stops making progress.
        let max_steps = 8 * vertices + 16;
        for _ in 0..max_steps {
            self.settle()?;
            if self.loops.is_empty() {
                return Ok(());
            }
            let (t, event) = self.next_event().ok_or(SkeletonError::Inconsistent)?;
            self.time = self.time.max(t);
            match event {
                Event::Edge { l, i } => self.edge_event(l, i),
                Event::Split { l, i, m, j } => self.split_event(l, i, m, j),
            }
        }
        Err(SkeletonError::Inconsistent)
    }

    /// Resolves what needs no time: vertices between facing edges lay their ridge, and loops of
    /// two vertices close.
    fn settle(&mut self) -> Result<(), SkeletonError> {
        let mut guard = 0;
        loop {
            guard += 1;
            if guard > 100_000 {
                return Err(SkeletonError::Inconsistent);
            }
            if let Some(l) = self.loops.iter().position(|lp| lp.len() <= 2) {
                let lp = self.loops.swap_remove(l);
                self.close(&lp)?;
                continue;
            }
            let facing = self.loops.iter().enumerate().find_map(|(l, lp)| {
                lp.iter()
                    .position(|v| self.velocity(v.left, v.right).is_none())
                    .map(|i| (l, i))
            });
            match facing {
                Some((l, i)) => self.ridge(l, i),
                None => return Ok(()),
            }
        }
    }

    /// A loop of two vertices: the two edges between them lie on one line, facing each other;
    /// each vertex walks to where it is now, and an arc joins them.
    fn close(&mut self, lp: &[Vertex]) -> Result<(), SkeletonError> {
        if lp.len() < 2 {
            return Err(SkeletonError::Inconsistent);
        }
        let mut ends = [0; 2];
        for (k, v) in lp.iter().enumerate() {
            let at = v.at(self.time);
            let start = self.nodes[v.node].at;
            ends[k] = if planar_length(at[0] - start[0], at[1] - start[1]) > SAME_POINT {
                let n = self.node(at);
                self.end(v, n);
                n
            } else {
                v.node
            };
        }
        self.arcs.push(Arc {
            nodes: ends,
            faces: [lp[0].right, lp[1].right],
        });
        Ok(())
    }

    /// Vertex `i` of loop `l` stands between edges that face each other on one line: their
    /// common stretch is a ridge, laid now from the vertex to the nearer of its neighbours,
    /// which takes its place.
    fn ridge(&mut self, l: usize, i: usize) {
        let n = self.loops[l].len();
        let (p, q) = ((i + n - 1) % n, (i + 1) % n);
        let lp = &self.loops[l];
        let (v, prev, next) = (lp[i], lp[p], lp[q]);
        let here = v.at(self.time);
        let (dp, dq) = (
            dist(here, prev.at(self.time)),
            dist(here, next.at(self.time)),
        );
        let (near, k) = if dp <= dq { (prev, p) } else { (next, q) };
        let node = self.node(near.at(self.time));
        self.end(&v, node);
        self.end(&near, node);
        let merged = if dp <= dq {
            self.vertex(node, prev.left, v.right)
        } else {
            self.vertex(node, v.left, next.right)
        };
        let lp = &mut self.loops[l];
        lp[k] = merged;
        lp.remove(i);
    }

    /// The earliest event on the current wavefront, and its time.
    fn next_event(&self) -> Option<(f64, Event)> {
        let t = self.time;
        let mut best: Option<(f64, Event)> = None;
        fn offer(best: &mut Option<(f64, Event)>, time: f64, event: Event) {
            if best.is_none_or(|(b, _)| time < b) {
                *best = Some((time, event));
            }
        }
        for (l, lp) in self.loops.iter().enumerate() {
            let n = lp.len();
            for i in 0..n {
                let (v, w) = (&lp[i], &lp[(i + 1) % n]);
                let e = &self.edges[v.right];
                let gap = dot(sub(w.at(t), v.at(t)), e.u);
                let rate = dot(sub(w.vel, v.vel), e.u);
                if rate < -1e-12 {
                    offer(&mut best, t + gap.max(0.0) / -rate, Event::Edge { l, i });
                }
            }
        }
        for (l, lp) in self.loops.iter().enumerate() {
            for (i, v) in lp.iter().enumerate() {
                if !self.is_reflex(v) {
                    continue;
                }
                let here = v.at(t);
                for (m, other) in self.loops.iter().enumerate() {
                    let k = other.len();
                    for j in 0..k {
                        let (w1, w2) = (&other[j], &other[(j + 1) % k]);
                        let edge = w1.right;
                        if edge == v.left || edge == v.right {
                            continue;
                        }
                        let e = &self.edges[edge];
                        let ahead = e.distance(here) - t;
                        let closing = 1.0 - dot(v.vel, e.n);
                        if closing <= 1e-12 || ahead < -SAME_POINT {
                            continue;
                        }
                        let when = t + ahead.max(0.0) / closing;
                        if best.is_some_and(|(b, _)| when >= b) {
                            continue;
                        }
                        let hit = dot(sub(v.at(when), e.a), e.u);
                        let (s1, s2) = (
                            dot(sub(w1.at(when), e.a), e.u),
                            dot(sub(w2.at(when), e.a), e.u),
                        );
                        if hit >= s1 - SAME_POINT && hit <= s2 + SAME_POINT {
                            offer(&mut best, when, Event::Split { l, i, m, j });
                        }
                    }
                }
            }
        }
        best
    }

    fn edge_event(&mut self, l: usize, i: usize) {
        let n = self.loops[l].len();
        let j = (i + 1) % n;
        let (v, w) = (self.loops[l][i], self.loops[l][j]);
        let t = self.time;
        let at = scale(add(v.at(t), w.at(t)), 0.5);
        let node = self.node(at);
        self.end(&v, node);
        self.end(&w, node);
        let merged = self.vertex(node, v.left, w.right);
        let lp = &mut self.loops[l];
        lp[i] = merged;
        lp.remove(j);
    }

    fn split_event(&mut self, l: usize, i: usize, m: usize, j: usize) {
        let v = self.loops[l][i];
        let w1 = self.loops[m][j];
        let edge = w1.right;
        let node = self.node(v.at(self.time));
        self.end(&v, node);
        let va = self.vertex(node, v.left, edge);
        let vb = self.vertex(node, edge, v.right);
        // The vertices of a loop in order, from index `from` (inclusive) to `to` (inclusive),
        // going round.
        fn stretch(lp: &[Vertex], from: usize, to: usize) -> Vec<Vertex> {
            let n = lp.len();
            let count = (to + n - from) % n + 1;
            (0..count).map(|k| lp[(from + k) % n]).collect()
        }
        if l == m {
            let lp = self.loops.swap_remove(l);
            let n = lp.len();
            // Va, then w2 .. the vertex before v; Vb, then the vertex after v .. w1.
            let mut first = vec![va];
            first.extend(stretch(&lp, (j + 1) % n, (i + n - 1) % n));
            let mut second = vec![vb];
            second.extend(stretch(&lp, (i + 1) % n, j));
            self.loops.push(first);
            self.loops.push(second);
        } else {
            let (a, b) = (self.loops[l].clone(), self.loops[m].clone());
            let (na, nb) = (a.len(), b.len());
            // Va, all of the other loop from w2 round to w1, Vb, then v's loop from the vertex
            // after v round to the one before it.
            let mut joined = vec![va];
            joined.extend(stretch(&b, (j + 1) % nb, j));
            joined.push(vb);
            joined.extend(stretch(&a, (i + 1) % na, (i + na - 1) % na));
            let (hi, lo) = (l.max(m), l.min(m));
            self.loops.swap_remove(hi);
            self.loops.swap_remove(lo);
            self.loops.push(joined);
        }
    }

    /// Nodes at one place and time merged, arcs of no length dropped, and each edge's face
    /// chained from its arcs.
    pub(super) fn into_skeleton(self, vertices: usize) -> Result<Skeleton, SkeletonError> {
        // Merge coincident nodes (events at one point make one node each).
        let mut nodes: Vec<SkeletonNode> = Vec::new();
        let mut index: Vec<usize> = Vec::with_capacity(self.nodes.len());
        for (k, node) in self.nodes.iter().enumerate() {
            let found = nodes.iter().position(|m| {
                dist(m.at, node.at) <= 1e-6 * (1.0 + node.time) && (m.time - node.time).abs() < 1e-6
            });
            match found {
                Some(f) if k >= vertices => index.push(f),
                _ => {
                    nodes.push(*node);
                    index.push(nodes.len() - 1);
                }
            }
        }
        let mut arcs: Vec<Arc> = Vec::new();
        for arc in &self.arcs {
            let (a, b) = (index[arc.nodes[0]], index[arc.nodes[1]]);
            if a != b && arc.faces[0] != arc.faces[1] {
                arcs.push(Arc {
                    nodes: [a, b],
                    faces: arc.faces,
                });
            }
        }
        let mut faces = Vec::with_capacity(self.edges.len());
        for e in 0..self.edges.len() {
            faces.push(chain_face(e, self.edge_ends[e], &arcs)?);
        }
        Ok(Skeleton {
            nodes,
            edges: self.edges,
            faces,
            arcs,
        })
    }
}

//! The straight skeleton of a footprint with courtyards (docs/method.md section 6b): every edge
//! of the outline moves inwards at unit speed, parallel to itself; where the moving edges meet
//! they trace the skeleton's arcs, and each edge sweeps one face. A hipped roof of one pitch is
//! that sweep lifted by the time each point is reached, so every face is planar and rises from
//! its own edge.
//!
//! The wavefront is simulated event by event: at each step every possible next event is
//! measured on the current wavefront (an edge shrinking to nothing, or a reflex vertex running
//! into an edge and splitting the wavefront, or joining a courtyard's wavefront to the outer one)
//! and the earliest is applied. Recomputing all events at each step costs O(n²) per event, O(n³)
//! per footprint; [`MAX_SKELETON_VERTICES`] bounds it, and footprints over it keep the virtual
//! rectangle. Two edges that become adjacent while parallel and facing each other (the end of a
//! wing, seen from its ridge) meet along their whole common stretch at once: the ridge is laid
//! at that moment rather than simulated.
//!
//! The result is checked before use: every face closes, the faces' areas sum to the
//! footprint's, and every node lies on the plane of each face it bounds. A footprint that fails
//! (numerically unlucky coincidences of events) gets [`SkeletonError::Inconsistent`], and its
//! roof keeps the virtual rectangle.

use super::length::planar_length;

/// Most vertices (outline and courtyards together) a footprint may have for its skeleton: the
/// worst case measured (a 128-pointed star, all its events at once, shaken) takes 7.3 ms here;
/// real outlines of this size take well under 1 ms.
pub const MAX_SKELETON_VERTICES: usize = 128;

/// Edges whose inward normals are closer than this to opposite (`1 + n1.n2`) are taken as
/// parallel and facing: their wavefronts meet along their whole common stretch.
const FACING: f64 = 1e-12;

/// Lengths (m) below which two points of the wavefront are one.
const SAME_POINT: f64 = 1e-7;

/// How far (m) an outline's points are moved, at most, when its exact skeleton cannot be
/// simulated ([`Skeleton::of`]).
pub const SHAKE: f64 = 1e-4;

/// Shaken outlines tried before giving up.
const SHAKE_TRIES: u64 = 3;

/// A fixed pseudo-random offset of at most [`SHAKE`] for point `i` of ring `r`: the same on
/// every run, so the same outline always gets the same roof.
fn shake(seed: u64, r: usize, i: usize) -> [f64; 2] {
    let mut x = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((r as u64) << 32 | i as u64);
    let mut next = || {
        // splitmix64
        x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = x;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    [SHAKE * next(), SHAKE * next()]
}

/// Why a footprint has no skeleton.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SkeletonError {
    #[error("the footprint has more vertices than the skeleton takes")]
    TooManyVertices,
    #[error("the outline doubles back on itself (a spike)")]
    Spike,
    #[error("the wavefront did not resolve into closed planar faces")]
    Inconsistent,
}

/// A point of the skeleton: where it stands, and when the wavefront reaches it (its distance
/// from the nearest edge whose face it bounds, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkeletonNode {
    pub at: [f64; 2],
    pub time: f64,
}

/// One edge of the input as a line: a point on it, its unit direction, and the unit normal
/// pointing into the footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeLine {
    pub a: [f64; 2],
    pub b: [f64; 2],
    pub u: [f64; 2],
    pub n: [f64; 2],
}

impl EdgeLine {
    fn new(a: [f64; 2], b: [f64; 2]) -> Self {
        let d = sub(b, a);
        let len = planar_length(d[0], d[1]);
        let u = [d[0] / len, d[1] / len];
        Self {
            a,
            b,
            u,
            n: [-u[1], u[0]],
        }
    }

    /// How far `p` lies inside the edge's line: the time the wavefront of this edge reaches it.
    #[inline]
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        dot(sub(p, self.a), self.n)
    }
}

/// The straight skeleton: nodes, the face each input edge sweeps, and the arcs between faces.
#[derive(Debug, Clone)]
pub struct Skeleton {
    pub nodes: Vec<SkeletonNode>,
    /// One line per input edge: the outer ring's edges first, then each courtyard's, each ring
    /// in its order (edge `i` runs from point `i` to point `i + 1`).
    pub edges: Vec<EdgeLine>,
    /// The face each edge sweeps: node indices counter-clockwise, starting with the edge's own
    /// two ends.
    pub faces: Vec<Vec<usize>>,
    /// Where two faces meet: the two nodes and the two edges whose faces it divides.
    pub arcs: Vec<Arc>,
}

/// A skeleton arc: from node to node, between the faces of two edges.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arc {
    pub nodes: [usize; 2],
    pub faces: [usize; 2],
}

impl Skeleton {
    /// The skeleton of a footprint: `rings[0]` is the outline, counter-clockwise; the others are
    /// courtyards, clockwise (the footprint's interior on the left of every edge). Points must be
    /// distinct and the rings simple and disjoint, as [`super::footprint::Footprint`] makes them.
    ///
    /// Many events at one point and moment (the reflex corners of a regular star all reaching
    /// its centre together) can defeat the event-by-event simulation; then the outline is
    /// shaken by at most [`SHAKE`] metres, which parts the events, and the skeleton of the
    /// shaken outline is used with its outline points put back where they were (its inner nodes
    /// stay within about [`SHAKE`] of where the exact skeleton has them).
    pub fn of(rings: &[&[[f64; 2]]]) -> Result<Self, SkeletonError> {
        match Self::exact(rings) {
            Err(SkeletonError::Inconsistent) => {}
            done => return done,
        }
        let mut last = SkeletonError::Inconsistent;
        for seed in 1..=SHAKE_TRIES {
            let shaken: Vec<Vec<[f64; 2]>> = rings
                .iter()
                .enumerate()
                .map(|(r, ring)| {
                    ring.iter()
                        .enumerate()
                        .map(|(i, p)| {
                            let [dx, dy] = shake(seed, r, i);
                            [p[0] + dx, p[1] + dy]
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[[f64; 2]]> = shaken.iter().map(Vec::as_slice).collect();
            match Self::exact(&refs) {
                Ok(mut skeleton) => {
                    skeleton.restore_outline(rings);
                    return Ok(skeleton);
                }
                Err(e) => last = e,
            }
        }
        Err(last)
    }

    /// The skeleton by simulation alone, without shaking.
    fn exact(rings: &[&[[f64; 2]]]) -> Result<Self, SkeletonError> {
        let total: usize = rings.iter().map(|r| r.len()).sum();
        if total > MAX_SKELETON_VERTICES {
            return Err(SkeletonError::TooManyVertices);
        }
        if rings.is_empty() || rings.iter().any(|r| r.len() < 3) {
            return Err(SkeletonError::Inconsistent);
        }
        // Work near the origin, for precision far from the frame's.
        let origin = rings[0][0];
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
        wave.run(total)?;
        let mut skeleton = wave.into_skeleton(total)?;
        for node in &mut skeleton.nodes {
            node.at = add(node.at, origin);
        }
        skeleton.restore_outline(rings);
        skeleton.check(rings)?;
        Ok(skeleton)
    }

    /// The outline's own points and lines exactly as given (the simulation ran near the origin,
    /// or on a shaken outline).
    fn restore_outline(&mut self, rings: &[&[[f64; 2]]]) {
        let mut k = 0;
        for ring in rings {
            for (i, p) in ring.iter().enumerate() {
                self.nodes[k + i].at = *p;
                self.edges[k + i] = EdgeLine::new(*p, ring[(i + 1) % ring.len()]);
            }
            k += ring.len();
        }
    }

    /// The latest time any node is reached: the roof's run from eaves to top.
    pub fn max_time(&self) -> f64 {
        self.nodes.iter().map(|n| n.time).fold(0.0, f64::max)
    }

    /// The face polygon of edge `e` in metres.
    pub fn face_points(&self, e: usize) -> Vec<[f64; 2]> {
        self.faces[e].iter().map(|&k| self.nodes[k].at).collect()
    }

    /// What every skeleton promises: the faces' areas sum to the footprint's, no face turns
    /// clockwise, and each node lies on the plane of every face it bounds.
    fn check(&self, rings: &[&[[f64; 2]]]) -> Result<(), SkeletonError> {
        let area: f64 = rings.iter().map(|r| twice_area(r)).sum::<f64>() / 2.0;
        let scale = rings[0]
            .iter()
            .map(|p| planar_length(p[0] - rings[0][0][0], p[1] - rings[0][0][1]))
            .fold(1.0, f64::max);
        let mut sum = 0.0;
        for (e, face) in self.faces.iter().enumerate() {
            let a = twice_area(&self.face_points(e)) / 2.0;
            if a < -1e-9 * scale * scale {
                return Err(SkeletonError::Inconsistent);
            }
            sum += a;
            for &k in face {
                let node = self.nodes[k];
                if (self.edges[e].distance(node.at) - node.time).abs() > 1e-6 * scale {
                    return Err(SkeletonError::Inconsistent);
                }
            }
        }
        if (sum - area).abs() > 1e-7 * area.max(1.0) {
            return Err(SkeletonError::Inconsistent);
        }
        Ok(())
    }
}

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

#[derive(Default)]
struct Wavefront {
    edges: Vec<EdgeLine>,
    nodes: Vec<SkeletonNode>,
    loops: Vec<Vec<Vertex>>,
    arcs: Vec<Arc>,
    /// The input point each edge ends at (its start is the point of its own index).
    edge_ends: Vec<usize>,
    time: f64,
}

impl Wavefront {
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

    /// A new vertex at `node` between `left` and `right`; `None` when they face each other.
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

    fn run(&mut self, vertices: usize) -> Result<(), SkeletonError> {
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
    fn into_skeleton(self, vertices: usize) -> Result<Skeleton, SkeletonError> {
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
        let rep = index;
        let mut arcs: Vec<Arc> = Vec::new();
        for arc in &self.arcs {
            let (a, b) = (rep[arc.nodes[0]], rep[arc.nodes[1]]);
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

/// The face of edge `e` from `start` to `end`: its arcs chained from `end` back to `start`.
fn chain_face(e: usize, end: usize, arcs: &[Arc]) -> Result<Vec<usize>, SkeletonError> {
    let start = e;
    // The arcs of this face, a pair that appears twice (there and back) cancelling out.
    let mut own: Vec<[usize; 2]> = Vec::new();
    for arc in arcs.iter().filter(|a| a.faces.contains(&e)) {
        let key = [
            arc.nodes[0].min(arc.nodes[1]),
            arc.nodes[0].max(arc.nodes[1]),
        ];
        match own.iter().position(|k| *k == key) {
            Some(p) => {
                own.swap_remove(p);
            }
            None => own.push(key),
        }
    }
    let mut face = vec![start, end];
    let mut used = vec![false; own.len()];
    let mut cur = end;
    while cur != start {
        let mut next = None;
        for (k, arc) in own.iter().enumerate() {
            if used[k] || !arc.contains(&cur) {
                continue;
            }
            if next.is_some() {
                // A node with more than two arcs of this face.
                return Err(SkeletonError::Inconsistent);
            }
            next = Some((k, if arc[0] == cur { arc[1] } else { arc[0] }));
        }
        let Some((k, node)) = next else {
            return Err(SkeletonError::Inconsistent);
        };
        used[k] = true;
        cur = node;
        if cur != start {
            face.push(cur);
        }
    }
    if used.iter().any(|u| !u) {
        return Err(SkeletonError::Inconsistent);
    }
    Ok(face)
}

fn twice_area(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    let o = points[0];
    (1..n.saturating_sub(1))
        .map(|i| cross(sub(points[i], o), sub(points[i + 1], o)))
        .sum()
}

#[inline]
fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}
#[inline]
fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
#[inline]
fn scale(a: [f64; 2], k: f64) -> [f64; 2] {
    [a[0] * k, a[1] * k]
}
#[inline]
fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
#[inline]
fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}
#[inline]
fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    planar_length(a[0] - b[0], a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn skeleton(rings: &[Vec<[f64; 2]>]) -> Skeleton {
        let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
        Skeleton::of(&refs).unwrap()
    }

    fn times(s: &Skeleton) -> Vec<f64> {
        let mut t: Vec<f64> = s.nodes.iter().map(|n| n.time).collect();
        t.sort_by(f64::total_cmp);
        t
    }

    #[test]
    fn a_rectangle_has_a_ridge_and_four_hips() {
        // 20 m by 8 m: the ridge runs from (4, 4) to (16, 4), reached at 4 m.
        let s = skeleton(&[vec![[0.0, 0.0], [20.0, 0.0], [20.0, 8.0], [0.0, 8.0]]]);
        assert_eq!(s.nodes.len(), 6);
        assert_eq!(times(&s)[4..], [4.0, 4.0]);
        let mut ridge: Vec<[f64; 2]> = s.nodes[4..].iter().map(|n| n.at).collect();
        ridge.sort_by(|a, b| a[0].total_cmp(&b[0]));
        assert!((ridge[0][0] - 4.0).abs() < 1e-9 && (ridge[0][1] - 4.0).abs() < 1e-9);
        assert!((ridge[1][0] - 16.0).abs() < 1e-9 && (ridge[1][1] - 4.0).abs() < 1e-9);
        // Two trapezoids along the long sides, two triangles at the ends.
        let sizes: Vec<usize> = s.faces.iter().map(Vec::len).collect();
        assert_eq!(sizes, [4, 3, 4, 3]);
        assert_eq!(s.arcs.len(), 5);
    }

    #[test]
    fn a_square_meets_in_its_centre() {
        let s = skeleton(&[vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]]);
        assert_eq!(s.nodes.len(), 5);
        assert_eq!(s.nodes[4].at, [5.0, 5.0]);
        assert_eq!(s.nodes[4].time, 5.0);
        assert!(s.faces.iter().all(|f| f.len() == 3));
    }

    #[test]
    fn an_l_has_a_ridge_along_each_wing_and_a_valley() {
        // Wings 6 m wide: 20 m along x, 14 m along y.
        let s = skeleton(&[vec![
            [0.0, 0.0],
            [20.0, 0.0],
            [20.0, 6.0],
            [6.0, 6.0],
            [6.0, 14.0],
            [0.0, 14.0],
        ]]);
        assert!((s.max_time() - 3.0).abs() < 1e-9);
        // The ridge of the long wing ends 3 m from its end wall, at (17, 3); the other's at (3, 11).
        let at = |p: [f64; 2]| {
            s.nodes
                .iter()
                .any(|n| dist(n.at, p) < 1e-9 && n.time == 3.0)
        };
        assert!(at([17.0, 3.0]) && at([3.0, 11.0]) && at([3.0, 3.0]));
        // The valley runs from the inner corner (6, 6) to (3, 3).
        assert!(s.arcs.iter().any(|a| {
            let (p, q) = (s.nodes[a.nodes[0]].at, s.nodes[a.nodes[1]].at);
            (p == [6.0, 6.0] && dist(q, [3.0, 3.0]) < 1e-9)
                || (q == [6.0, 6.0] && dist(p, [3.0, 3.0]) < 1e-9)
        }));
    }

    #[test]
    fn a_courtyard_gets_its_own_eaves() {
        // A 30 m square around a 10 m courtyard: a ring of roof 10 m wide, its ridge 5 m in.
        let s = skeleton(&[
            vec![[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [0.0, 30.0]],
            vec![[10.0, 10.0], [10.0, 20.0], [20.0, 20.0], [20.0, 10.0]],
        ]);
        assert_eq!(s.faces.len(), 8);
        assert!((s.max_time() - 5.0).abs() < 1e-9);
        for n in &s.nodes[8..] {
            assert!((n.time - 5.0).abs() < 1e-9, "{n:?}");
        }
    }

    #[test]
    fn symmetric_outlines_where_events_coincide() {
        let shapes: [&[[f64; 2]]; 5] = [
            // A plus: four reflex corners reach the centre together.
            &[
                [4.0, 0.0],
                [8.0, 0.0],
                [8.0, 4.0],
                [12.0, 4.0],
                [12.0, 8.0],
                [8.0, 8.0],
                [8.0, 12.0],
                [4.0, 12.0],
                [4.0, 8.0],
                [0.0, 8.0],
                [0.0, 4.0],
                [4.0, 4.0],
            ],
            // An H.
            &[
                [0.0, 0.0],
                [4.0, 0.0],
                [4.0, 6.0],
                [10.0, 6.0],
                [10.0, 0.0],
                [14.0, 0.0],
                [14.0, 16.0],
                [10.0, 16.0],
                [10.0, 10.0],
                [4.0, 10.0],
                [4.0, 16.0],
                [0.0, 16.0],
            ],
            // A T.
            &[
                [0.0, 10.0],
                [6.0, 10.0],
                [6.0, 0.0],
                [12.0, 0.0],
                [12.0, 10.0],
                [18.0, 10.0],
                [18.0, 16.0],
                [0.0, 16.0],
            ],
            // A U, wings as wide as the base.
            &[
                [0.0, 0.0],
                [20.0, 0.0],
                [20.0, 15.0],
                [14.0, 15.0],
                [14.0, 6.0],
                [6.0, 6.0],
                [6.0, 15.0],
                [0.0, 15.0],
            ],
            // A comb of three teeth.
            &[
                [0.0, 0.0],
                [22.0, 0.0],
                [22.0, 12.0],
                [18.0, 12.0],
                [18.0, 5.0],
                [13.0, 5.0],
                [13.0, 12.0],
                [9.0, 12.0],
                [9.0, 5.0],
                [4.0, 5.0],
                [4.0, 12.0],
                [0.0, 12.0],
            ],
        ];
        for ring in shapes {
            let s = Skeleton::of(&[ring]);
            assert!(s.is_ok(), "{:?} on {ring:?}", s.err());
        }
    }

    #[test]
    fn regular_polygons_and_stars_where_every_event_is_at_once() {
        for n in [8usize, 24, 64] {
            let ring = |r_odd: f64| -> Vec<[f64; 2]> {
                (0..n)
                    .map(|k| {
                        let a = k as f64 / n as f64 * std::f64::consts::TAU;
                        let r = if k % 2 == 0 { 30.0 } else { r_odd };
                        [r * a.cos(), r * a.sin()]
                    })
                    .collect()
            };
            // A regular polygon meets in its centre, at its inradius.
            let s = skeleton(&[ring(30.0)]);
            let inradius = 30.0 * (std::f64::consts::PI / n as f64).cos();
            assert!((s.max_time() - inradius).abs() < 1e-9, "{n}-gon");
            assert!(s.faces.iter().all(|f| f.len() == 3), "{n}-gon");
            // A star: its reflex corners all reach the centre together (shaken apart for
            // n >= 24); the outline's points stay exactly where they were.
            let star = ring(22.0);
            let s = skeleton(std::slice::from_ref(&star));
            for (k, p) in star.iter().enumerate() {
                assert_eq!(s.nodes[k].at, *p);
            }
            assert!(
                s.max_time() > 0.0 && s.max_time() < 22.0 + SHAKE,
                "{n}: {}",
                s.max_time()
            );
        }
    }

    #[test]
    fn too_many_vertices_are_refused() {
        let ring: Vec<[f64; 2]> = (0..MAX_SKELETON_VERTICES + 1)
            .map(|k| {
                let a = k as f64 / (MAX_SKELETON_VERTICES + 1) as f64 * std::f64::consts::TAU;
                [100.0 * a.cos(), 100.0 * a.sin()]
            })
            .collect();
        assert_eq!(
            Skeleton::of(&[&ring]).unwrap_err(),
            SkeletonError::TooManyVertices
        );
    }

    /// A star-shaped ring around `c` with radii `r` at jittered angles, counter-clockwise.
    fn star(c: [f64; 2], r: &[f64], jitter: &[f64]) -> Vec<[f64; 2]> {
        let n = r.len();
        (0..n)
            .map(|k| {
                let a = (k as f64 + 0.4 * jitter[k]) / n as f64 * std::f64::consts::TAU;
                [c[0] + r[k] * a.cos(), c[1] + r[k] * a.sin()]
            })
            .collect()
    }

    /// Rectilinear outlines, as many real buildings are: columns of the given widths, each
    /// from `-below` to `above` (U, H, comb and staircase shapes), counter-clockwise.
    fn blocks(widths: &[f64], below: &[f64], above: &[f64]) -> Vec<[f64; 2]> {
        let mut ring = Vec::new();
        let mut x = 0.0;
        for (w, b) in widths.iter().zip(below) {
            ring.push([x, -b]);
            ring.push([x + w, -b]);
            x += w;
        }
        for (w, a) in widths.iter().zip(above).rev() {
            ring.push([x, *a]);
            ring.push([x - w, *a]);
            x -= w;
        }
        // Drop repeated points (equal neighbours leave points in a row on one line: kept).
        ring.dedup_by(|a, b| dist(*a, *b) < 1e-9);
        if dist(ring[0], ring[ring.len() - 1]) < 1e-9 {
            ring.pop();
        }
        ring
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// On random star-shaped outlines, some with a courtyard: the skeleton exists and its
        /// check holds (faces tile the footprint, every node on each face's plane).
        #[test]
        fn random_outlines_have_consistent_skeletons(
            r in prop::collection::vec(8.0..30.0f64, 3..24),
            jitter in prop::collection::vec(-1.0..1.0f64, 24),
            hole in prop::option::of((0.5..3.0f64, 0.0..std::f64::consts::TAU)),
        ) {
            let outer = star([500.0, -300.0], &r, &jitter);
            let mut rings = vec![outer];
            if let Some((size, turn)) = hole {
                // A small square courtyard near the centre, clockwise.
                let (c, s) = (turn.cos() * size, turn.sin() * size);
                let courtyard = vec![
                    [500.0 - c + s, -300.0 - s - c],
                    [500.0 - c - s, -300.0 - s + c],
                    [500.0 + c - s, -300.0 + s + c],
                    [500.0 + c + s, -300.0 + s - c],
                ];
                // Only a courtyard well inside the outline.
                let o = &rings[0];
                prop_assume!(courtyard.iter().all(|&p| {
                    crate::building::footprint::inside(o, p)
                        && (0..o.len()).all(|k| {
                            crate::building::footprint::segment_distance(p, o[k], o[(k + 1) % o.len()]) > 0.5
                        })
                }));
                rings.push(courtyard);
            }
            let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
            let s = Skeleton::of(&refs);
            prop_assert!(s.is_ok(), "{:?} on {:?}", s.err(), rings);
        }

        /// Rectilinear outlines with many equal coordinates (simultaneous events, parallel
        /// edges meeting): the skeleton exists and its check holds.
        #[test]
        fn rectilinear_outlines_have_consistent_skeletons(
            widths in prop::collection::vec(prop::sample::select(vec![4.0, 6.0, 8.0, 10.0, 12.5]), 1..7),
            below in prop::collection::vec(prop::sample::select(vec![0.0, 2.0, 4.0, 6.0]), 7),
            above in prop::collection::vec(prop::sample::select(vec![4.0, 6.0, 8.0, 10.0, 14.0]), 7),
            courtyard in prop::option::of((0usize..7, 0.5..1.5f64)),
        ) {
            let n = widths.len();
            let ring = blocks(&widths, &below[..n], &above[..n]);
            let mut rings = vec![ring];
            if let Some((column, size)) = courtyard {
                // A square courtyard in the middle of one column, clockwise, if it fits.
                let k = column % n;
                let x: f64 = widths[..k].iter().sum::<f64>() + widths[k] / 2.0;
                let y = (above[k] - below[k]) / 2.0;
                let h = size.min(widths[k] / 4.0).min((above[k] + below[k]) / 4.0);
                rings.push(vec![[x - h, y - h], [x - h, y + h], [x + h, y + h], [x + h, y - h]]);
            }
            let refs: Vec<&[[f64; 2]]> = rings.iter().map(Vec::as_slice).collect();
            let s = Skeleton::of(&refs);
            prop_assert!(s.is_ok(), "{:?} on {:?}", s.err(), rings);
        }
    }
}

//! Disjoint sets over `0..n` (union by smaller index, path halving): buildings joined into
//! clusters, triangles joined into solids.

/// Disjoint sets over `0..n`.
pub(crate) struct UnionFind(Vec<usize>);

impl UnionFind {
    /// `n` sets of one each.
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n).collect())
    }

    /// The smallest member of `x`'s set.
    pub(crate) fn find(&mut self, mut x: usize) -> usize {
        while self.0[x] != x {
            self.0[x] = self.0[self.0[x]];
            x = self.0[x];
        }
        x
    }

    /// Joins the sets of `a` and `b`.
    pub(crate) fn union(&mut self, a: usize, b: usize) {
        let (a, b) = (self.find(a), self.find(b));
        if a != b {
            self.0[a.max(b)] = a.min(b);
        }
    }
}

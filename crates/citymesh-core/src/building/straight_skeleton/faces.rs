//! Each edge's face of a straight skeleton, chained from the arcs that bound it.

use super::{Arc, SkeletonError};

/// The face of edge `e` from `start` to `end`: its arcs chained from `end` back to `start`.
pub(super) fn chain_face(e: usize, end: usize, arcs: &[Arc]) -> Result<Vec<usize>, SkeletonError> {
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

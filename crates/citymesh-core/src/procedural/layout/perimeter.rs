//! Perimeter blocks: one building along the whole block edge around a courtyard, a polygon with
//! a hole, four to six levels.

use super::{Builder, Rect};

pub fn place(b: &mut Builder, block: Rect) {
    let outer = block.inset(2.0);
    let depth = b.between(10.0, 16.0);
    let court = outer.inset(depth);
    let holes: Vec<Vec<[f64; 2]>> = if court.width() >= 8.0 && court.height() >= 8.0 {
        // Courtyards run clockwise.
        let mut r = court.ring();
        r.reverse();
        vec![r]
    } else {
        Vec::new()
    };
    let levels = b.rng_levels(4, 6);
    let shape = b.roof_shape();
    let tags = b.tags("perimeter", "apartments", levels, shape, depth);
    b.add(&outer.ring(), &holes, false, tags);
}

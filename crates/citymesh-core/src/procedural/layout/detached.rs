//! Detached houses: a lot every 14 to 20 m along the block's long sides, a house of 8 to 12 m on
//! each, some of them L-shaped, one to three levels under a roof from the weights.

use super::{Builder, Rect};

pub fn place(b: &mut Builder, block: Rect) {
    let along_x = block.width() >= block.height();
    let (length, depth) = if along_x {
        (block.width(), block.height())
    } else {
        (block.height(), block.width())
    };
    // One row of lots when the block is shallow, two back to back otherwise.
    let rows = if depth >= 36.0 { 2 } else { 1 };
    let lot_depth = depth / f64::from(rows);
    let mut s = 0.0;
    while s + 14.0 <= length {
        let lot = b.between(14.0, 20.0).min(length - s);
        for row in 0..rows {
            let w = b.between(8.0, 12.0).min(lot - 4.0);
            let d = b.between(8.0, 12.0).min(lot_depth - 5.0);
            if w < 5.0 || d < 5.0 {
                continue;
            }
            // Local coordinates: u along the block, v into it from the street.
            let u0 = s + (lot - w) / 2.0;
            let v0 = if row == 0 { 3.0 } else { depth - 3.0 - d };
            let l_shape = b.between(0.0, 1.0) < 0.25;
            let local: Vec<[f64; 2]> = if l_shape {
                let (nw, nd) = (w * 0.45, d * 0.45);
                vec![
                    [u0, v0],
                    [u0 + w, v0],
                    [u0 + w, v0 + d - nd],
                    [u0 + w - nw, v0 + d - nd],
                    [u0 + w - nw, v0 + d],
                    [u0, v0 + d],
                ]
            } else {
                vec![[u0, v0], [u0 + w, v0], [u0 + w, v0 + d], [u0, v0 + d]]
            };
            let to_world = |[u, v]: [f64; 2]| {
                if along_x {
                    [block.x0 + u, block.y0 + v]
                } else {
                    [block.x1 - v, block.y0 + u]
                }
            };
            let ring: Vec<[f64; 2]> = local.into_iter().map(to_world).collect();
            let levels = b.rng_levels(1, 3);
            let shape = b.roof_shape();
            let tags = b.tags("detached", "house", levels, shape, w.min(d));
            b.add(&ring, &[], false, tags);
        }
        s += lot;
    }
}

//! Row houses: terraces of four to eight houses, 5 to 8 m wide, sharing their side walls exactly
//! (the same points, so the same nodes), along the block's long sides; one roof per terrace.

use super::{Builder, Rect};

pub fn place(b: &mut Builder, block: Rect) {
    let along_x = block.width() >= block.height();
    let (length, depth) = if along_x {
        (block.width(), block.height())
    } else {
        (block.height(), block.width())
    };
    let d = b.between(9.0, 12.0).min(depth - 6.0);
    if d < 6.0 {
        return;
    }
    let back_row = depth >= 2.0 * (d + 3.0) + 4.0;
    let rows: &[f64] = if back_row {
        &[3.0, depth - 3.0 - d]
    } else {
        &[3.0]
    };
    let to_world = |[u, v]: [f64; 2]| {
        if along_x {
            [block.x0 + u, block.y0 + v]
        } else {
            [block.x1 - v, block.y0 + u]
        }
    };
    for &v0 in rows {
        let mut s = 2.0;
        while s + 15.0 <= length - 2.0 {
            let houses = b.rng_levels(4, 8);
            let levels = b.rng_levels(2, 3);
            let shape = b.roof_shape();
            let mut u = s;
            for _ in 0..houses {
                let w = b.between(5.0, 8.0);
                if u + w > length - 2.0 {
                    break;
                }
                let ring: Vec<[f64; 2]> = [[u, v0], [u + w, v0], [u + w, v0 + d], [u, v0 + d]]
                    .into_iter()
                    .map(to_world)
                    .collect();
                let tags = b.tags("row", "terrace", levels, shape, w.min(d));
                b.add(&ring, &[], false, tags);
                u += w;
            }
            s = u + b.between(4.0, 8.0);
        }
    }
}

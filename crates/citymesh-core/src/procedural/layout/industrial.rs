//! Industrial halls: one or two large flat-roofed halls filling the block, 6 to 12 m high.

use super::{Builder, Rect};
use crate::building::roof::RoofShape;

pub fn place(b: &mut Builder, block: Rect) {
    let yard = block.inset(b.between(4.0, 8.0));
    let halls: Vec<Rect> = if yard.width() > 120.0 {
        let mid = (yard.x0 + yard.x1) / 2.0;
        vec![
            Rect {
                x1: mid - 5.0,
                ..yard
            },
            Rect {
                x0: mid + 5.0,
                ..yard
            },
        ]
    } else if yard.height() > 120.0 {
        let mid = (yard.y0 + yard.y1) / 2.0;
        vec![
            Rect {
                y1: mid - 5.0,
                ..yard
            },
            Rect {
                y0: mid + 5.0,
                ..yard
            },
        ]
    } else {
        vec![yard]
    };
    for hall in halls {
        let mut tags = b.tags("industrial", "industrial", 1, RoofShape::Flat, hall.width());
        let h = b.between(6.0, 12.0);
        if let Some(t) = tags.iter_mut().find(|(k, _)| *k == "height") {
            t.1 = Builder::metres(h);
        }
        b.add(&hall.ring(), &[], false, tags);
    }
}

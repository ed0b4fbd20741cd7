//! Towers: a `building` outline with two `building:part`s, a podium over the whole footprint and
//! a taller, slimmer tower standing on it (`min_height` = the podium's height). Flat roofs.

use super::{Builder, Rect};
use crate::building::roof::RoofShape;

pub fn place(b: &mut Builder, block: Rect) {
    let side = (block.width().min(block.height()) * 0.8).clamp(20.0, 40.0);
    let (cx, cy) = ((block.x0 + block.x1) / 2.0, (block.y0 + block.y1) / 2.0);
    let (w, h) = (side, side * b.between(0.7, 1.0));
    let podium = Rect {
        x0: cx - w / 2.0,
        y0: cy - h / 2.0,
        x1: cx + w / 2.0,
        y1: cy + h / 2.0,
    };
    let f = b.between(0.45, 0.7);
    let tower = Rect {
        x0: cx - w * f / 2.0,
        y0: cy - h * f / 2.0,
        x1: cx + w * f / 2.0,
        y1: cy + h * f / 2.0,
    };
    let podium_levels = b.rng_levels(2, 4);
    let tower_levels = b.rng_levels(12, 36);
    let podium_height = f64::from(podium_levels) * 3.5;
    let tower_height = podium_height + f64::from(tower_levels) * 3.2;

    let mut outline = b.tags(
        "tower",
        "office",
        podium_levels + tower_levels,
        RoofShape::Flat,
        w,
    );
    set(&mut outline, "height", Builder::metres(tower_height));
    b.add(&podium.ring(), &[], false, outline);

    let mut base = b.tags("tower", "yes", podium_levels, RoofShape::Flat, w);
    set(&mut base, "height", Builder::metres(podium_height));
    rename_building(&mut base);
    b.add(&podium.ring(), &[], true, base);

    let mut top = b.tags(
        "tower",
        "yes",
        podium_levels + tower_levels,
        RoofShape::Flat,
        w,
    );
    set(&mut top, "height", Builder::metres(tower_height));
    top.push(("min_height", Builder::metres(podium_height)));
    rename_building(&mut top);
    b.add(&tower.ring(), &[], true, top);
}

fn set(tags: &mut [(&'static str, String)], key: &str, value: String) {
    if let Some(t) = tags.iter_mut().find(|(k, _)| *k == key) {
        t.1 = value;
    }
}

/// Parts are tagged `building:part`, not `building`.
fn rename_building(tags: &mut [(&'static str, String)]) {
    if let Some(t) = tags.iter_mut().find(|(k, _)| *k == "building") {
        t.0 = "building:part";
    }
}

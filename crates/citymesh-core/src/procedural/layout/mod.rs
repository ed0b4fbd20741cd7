//! The block layouts: each fills one block of the city with buildings of its kind.

mod detached;
mod industrial;
mod perimeter;
mod row;
mod tower;

use super::builder::{Builder, Rect};
use super::params::LayoutType;

/// Fills `block` with buildings of the layout.
pub fn place(layout: LayoutType, b: &mut Builder, block: Rect) {
    match layout {
        LayoutType::Detached => detached::place(b, block),
        LayoutType::Row => row::place(b, block),
        LayoutType::Perimeter => perimeter::place(b, block),
        LayoutType::Tower => tower::place(b, block),
        LayoutType::Industrial => industrial::place(b, block),
    }
}

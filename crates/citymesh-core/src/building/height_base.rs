//! Where a building's `height` is measured from on sloping ground (docs/method.md section 3).
//! OpenStreetMap's Simple 3D Buildings measures `height` from the lowest ground at the outline;
//! the paper (its Figure 5) puts the top at the highest ground plus `height`, which on a slope
//! makes every building taller than tagged by the ground's rise under it.

/// The ground a building's `height` is counted from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum HeightBase {
    /// Simple 3D Buildings: the lowest ground along the outline (the default).
    #[default]
    LowestGround,
    /// The paper's rule: the highest ground along the outline.
    HighestGround,
}

/// On a slope steeper than the building is tall, its top still stands this far (m) above the
/// highest ground along its outline (or `height`, if lower), so no building is buried uphill.
pub const MIN_TOP_ABOVE_HIGHEST_GROUND: f64 = 1.0;

impl HeightBase {
    /// The height (m, in the model's reference) of the top of a building `height` tall whose
    /// outline's ground spans `lowest..=highest`.
    pub fn top(self, lowest: f64, highest: f64, height: f64) -> f64 {
        match self {
            HeightBase::LowestGround => {
                (lowest + height).max(highest + height.min(MIN_TOP_ABOVE_HIGHEST_GROUND))
            }
            HeightBase::HighestGround => highest + height,
        }
    }

    /// The name used by flags and query parameters.
    pub fn name(self) -> &'static str {
        match self {
            HeightBase::LowestGround => "lowest",
            HeightBase::HighestGround => "highest",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_top_is_counted_from_the_chosen_ground() {
        // A 30 m building on ground from 100 m to 112 m.
        assert_eq!(HeightBase::LowestGround.top(100.0, 112.0, 30.0), 130.0);
        assert_eq!(HeightBase::HighestGround.top(100.0, 112.0, 30.0), 142.0);
        // On flat ground both agree.
        assert_eq!(HeightBase::LowestGround.top(50.0, 50.0, 0.5), 50.5);
        assert_eq!(HeightBase::HighestGround.top(50.0, 50.0, 0.5), 50.5);
        // A 5 m shed on a 12 m rise keeps its top 1 m above the uphill ground.
        assert_eq!(HeightBase::LowestGround.top(100.0, 112.0, 5.0), 113.0);
    }
}

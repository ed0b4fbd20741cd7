//! One memory budget (`--memory-mb`) for every cache that holds data in memory, split in fixed
//! shares. Each cache weighs its entries in bytes (an upper bound of what they occupy) and
//! evicts the least recently used past its share, so their sum stays under the budget.

/// Shares of the budget, in percent: generated tiles and box scenes, parsed DEM files, parsed
/// OSM data tiles, the building sets made of them (which share the parsed records but are
/// weighed as if they did not), and roof priors.
const TILES: u64 = 25;
const DEM: u64 = 25;
const OSM_TILES: u64 = 20;
const BUILDING_SETS: u64 = 28;
const ROOF_PRIORS: u64 = 2;

/// The bytes each in-memory cache may hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryBudget {
    pub total: u64,
    /// Generated tiles (three quarters) and box scenes (a quarter).
    pub tiles: u64,
    pub dem: u64,
    pub osm_tiles: u64,
    pub building_sets: u64,
    pub roof_priors: u64,
}

impl MemoryBudget {
    /// Splits `megabytes`.
    pub fn of_megabytes(megabytes: u64) -> Self {
        let total = megabytes.saturating_mul(1 << 20);
        let share = |percent: u64| total / 100 * percent;
        Self {
            total,
            tiles: share(TILES),
            dem: share(DEM),
            osm_tiles: share(OSM_TILES),
            building_sets: share(BUILDING_SETS),
            roof_priors: share(ROOF_PRIORS),
        }
    }
}

/// A cache entry's weight for moka: its bytes, saturating at `u32::MAX`.
pub fn weight(bytes: usize) -> u32 {
    u32::try_from(bytes).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shares_add_up_to_no_more_than_the_budget() {
        for mb in [1, 7, 1024, 65_536] {
            let b = MemoryBudget::of_megabytes(mb);
            assert!(b.tiles + b.dem + b.osm_tiles + b.building_sets + b.roof_priors <= b.total);
            assert_eq!(TILES + DEM + OSM_TILES + BUILDING_SETS + ROOF_PRIORS, 100);
        }
        let b = MemoryBudget::of_megabytes(1000);
        assert_eq!(b.dem, 262_144_000);
    }
}

//! The lowest and highest ground along a closed ring (Elev_min and Elev_max of docs/method.md
//! section 3). The ground is linear on each mesh triangle, so along a straight edge its extremes
//! lie at the edge's ends or where it crosses a mesh line: a cell border (`u` or `v` at a half
//! step) or a cell diagonal (`u - v` or `u + v` whole, in sample units). Checking exactly those
//! points gives the exact range, so no footprint corner or edge floats above the ground.

use super::model::ElevationModel;

impl ElevationModel {
    /// `(min, max)` of the placement height ([`ElevationModel::ground_height`]) along the closed
    /// ring of (lon, lat) points.
    pub fn height_range_along(&self, ring: &[(f64, f64)]) -> (f64, f64) {
        let p = f64::from(self.per_degree());
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let mut cell = None;
        let mut visit = |lon: f64, lat: f64| {
            let h = self.ground_height_near(lon, lat, &mut cell);
            lo = lo.min(h);
            hi = hi.max(h);
        };
        let n = ring.len();
        for i in 0..n {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            visit(a.0, a.1);
            if self.is_empty() {
                continue;
            }
            let (u0, v0, u1, v1) = (a.0 * p, a.1 * p, b.0 * p, b.1 * p);
            // Each family of mesh lines as a linear function of (u, v) and its offset.
            let families: [(f64, f64, f64); 4] = [
                (1.0, 0.0, 0.5),
                (0.0, 1.0, 0.5),
                (1.0, -1.0, 0.0),
                (1.0, 1.0, 0.0),
            ];
            for (cu, cv, offset) in families {
                let f0 = cu * u0 + cv * v0 - offset;
                let f1 = cu * u1 + cv * v1 - offset;
                let (k0, k1) = (f0.min(f1).ceil() as i64, f0.max(f1).floor() as i64);
                if f0 == f1 || k1 < k0 || k1 - k0 > 10_000 {
                    continue;
                }
                for k in k0..=k1 {
                    let t = (k as f64 - f0) / (f1 - f0);
                    visit(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
                }
            }
        }
        if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) }
    }

    /// `(min, max)` of the placement height over `bbox`: every grid sample in it and one step
    /// around it, and its corners. A ground mesh over the box (full or coarse, both interpolate
    /// the samples) lies within it: what a tile's bounding region takes for its ground.
    pub fn height_range_in(&self, bbox: &crate::geo::GeoBbox) -> (f64, f64) {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let mut visit = |h: f64| {
            lo = lo.min(h);
            hi = hi.max(h);
        };
        for (lon, lat) in [
            (bbox.min_lon(), bbox.min_lat()),
            (bbox.max_lon(), bbox.min_lat()),
            (bbox.min_lon(), bbox.max_lat()),
            (bbox.max_lon(), bbox.max_lat()),
        ] {
            visit(self.ground_height(lon, lat));
        }
        if self.is_empty() {
            return (lo, hi);
        }
        let p = f64::from(self.per_degree());
        let (i0, i1) = (
            (bbox.min_lon() * p).floor() as i64 - 1,
            (bbox.max_lon() * p).ceil() as i64 + 1,
        );
        let (j0, j1) = (
            (bbox.min_lat() * p).floor() as i64 - 1,
            (bbox.max_lat() * p).ceil() as i64 + 1,
        );
        for j in j0..=j1 {
            for i in i0..=i1 {
                visit(self.ground_height(i as f64 / p, j as f64 / p));
            }
        }
        (lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use crate::terrain::{ElevationModel, HgtTile};
    use std::sync::Arc;

    #[test]
    fn finds_the_peak_between_two_corners() {
        // A single high sample at the centre of a cell: an edge passing near it rises between
        // its ends, where it crosses the cell's diagonals.
        let mut s = vec![100i16; 1201 * 1201];
        // Row 600 from the north, column 600: lat 49.5, lon 8.5.
        s[600 * 1201 + 600] = 200;
        let tile = Arc::new(HgtTile::from_samples(49, 8, s).unwrap());
        let m = ElevationModel::new(vec![tile]);
        let step = 1.0 / 1200.0;
        let ring = [
            (8.5 - 0.4 * step, 49.5),
            (8.5 + 0.4 * step, 49.5),
            (8.5, 49.5 + 0.4 * step),
        ];
        let (lo, hi) = m.height_range_along(&ring);
        let peak = m.ground_height(8.5, 49.5);
        assert_eq!(peak, 200.0);
        // The edge through the centre reaches it although no corner is there.
        assert!((hi - 200.0).abs() < 1e-9, "{hi}");
        assert!(lo < hi);
    }
}

//! Nothing lost or added unreported: after a group is meshed, each building's drawn floor must
//! cover the area its outline leaves (the outline less its courtyards and parts, as the boolean
//! cut answers it, less what the scene border cuts off). A floor that covers less means part of
//! the building (floor, walls and roof over it) went missing; one that covers more means a
//! courtyard or part was drawn over. Either is reported with the building's id.

use crate::mesh::{Material, Mesh};
use std::collections::BTreeMap;
use std::ops::Range;

/// For each building (feature row) of `wanted`, its wanted floor area less the area `drawn`
/// ([`floor_areas`]), m², where that differs from 0 by over `tolerance`: positive when area was
/// lost, negative when more was drawn.
pub fn uncovered_area(
    wanted: &BTreeMap<u32, f64>,
    drawn: &BTreeMap<u32, f64>,
    tolerance: f64,
) -> Vec<(u32, f64)> {
    wanted
        .iter()
        .filter_map(|(&feature, want)| {
            let lost = want - drawn.get(&feature).copied().unwrap_or(0.0);
            (lost.abs() > tolerance).then_some((feature, lost))
        })
        .collect()
}

/// The floor area of each building (feature row) among `triangles` of `mesh`, m².
pub fn floor_areas(mesh: &Mesh, triangles: Range<usize>) -> BTreeMap<u32, f64> {
    let mut drawn: BTreeMap<u32, f64> = BTreeMap::new();
    for t in triangles {
        let (Some(&tri), Some(style)) = (mesh.triangles.get(t), mesh.styles.get(t)) else {
            continue;
        };
        if style.material != Material::Floor {
            continue;
        }
        let [a, b, c] = mesh.corners(tri);
        let area = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() / 2.0;
        *drawn.entry(style.feature).or_default() += area;
    }
    drawn
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::building::axes::RoofAxes;
    use crate::building::footprint::{Footprint, FootprintRing};
    use crate::building::group::{Volume, mesh_group};
    use crate::building::roof::RoofShape;
    use crate::building::roof_surface::RoofSurface;
    use crate::building::tags::Orientation;
    use crate::mesh::Rgb;
    use std::borrow::Cow;

    #[test]
    fn a_floor_with_a_missing_piece_is_reported_with_what_it_lost() {
        // A 10 m x 6 m house and a 4 m x 3 m shed, meshed whole: nothing is lost.
        let square = |x0: f64, y0: f64, w: f64, h: f64| {
            Footprint::new(
                FootprintRing::from_points(vec![
                    [x0, y0],
                    [x0 + w, y0],
                    [x0 + w, y0 + h],
                    [x0, y0 + h],
                ]),
                vec![],
            )
            .unwrap()
        };
        let (house, shed) = (square(0.0, 0.0, 10.0, 6.0), square(20.0, 0.0, 4.0, 3.0));
        let roof = |f: &Footprint| {
            let axes = RoofAxes::of_ring(&f.outer.points).unwrap().long_first();
            RoofSurface::new(
                RoofShape::Gabled,
                axes,
                Orientation::Along,
                &f.outer.points,
                None,
                None,
            )
            .with_heights(8.0, 2.0)
        };
        let volume = |f: &Footprint, roof: usize, feature: u32| Volume {
            footprint: Cow::Owned(f.clone()),
            roof,
            floor: 0.0,
            wall_colour: Rgb(0, 0, 0),
            roof_colour: Rgb(0, 0, 0),
            feature,
        };
        let volumes = [volume(&house, 0, 0), volume(&shed, 1, 1)];
        let mut mesh = Mesh::default();
        mesh_group(&volumes, &[roof(&house), roof(&shed)], &mut mesh);
        let all = 0..mesh.triangles.len();
        let mut wanted = BTreeMap::from([(0, 60.0), (1, 12.0)]);
        assert_eq!(
            uncovered_area(&wanted, &floor_areas(&mesh, all.clone()), 1.0),
            vec![]
        );
        // A shed that should have been 4 m x 2 m was drawn 4 m² too big.
        wanted.insert(1, 8.0);
        assert_eq!(
            uncovered_area(&wanted, &floor_areas(&mesh, all.clone()), 1.0).len(),
            1
        );
        assert!(
            (uncovered_area(&wanted, &floor_areas(&mesh, all.clone()), 1.0)[0].1 + 4.0).abs()
                < 1e-9
        );
        wanted.insert(1, 12.0);

        // Drop one floor triangle of the house: half its floor (30 m²) or less goes missing.
        let floor = (0..mesh.triangles.len())
            .find(|&t| mesh.styles[t].material == Material::Floor && mesh.styles[t].feature == 0)
            .unwrap();
        let [a, b, c] = mesh.corners(mesh.triangles[floor]);
        let gone = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() / 2.0;
        mesh.styles[floor].material = Material::Wall;
        let lost = uncovered_area(&wanted, &floor_areas(&mesh, all.clone()), 1.0);
        assert_eq!(lost.len(), 1);
        assert_eq!(lost[0].0, 0);
        assert!(
            (lost[0].1 - gone).abs() < 1e-9 && gone > 1.0,
            "{lost:?}, {gone}"
        );
        // Under the tolerance it is not reported.
        assert_eq!(
            uncovered_area(&wanted, &floor_areas(&mesh, all), gone + 0.1),
            vec![]
        );
    }
}

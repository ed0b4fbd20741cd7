//! The pieces a footprint's volumes stand on: its parts and the courtyards it could not keep as
//! holes cut out, the scene border cut off (boolean operations), and every piece whose courtyard
//! touches its outline or another courtyard split apart, so each piece is simple.
//!
//! Every cut answers the area it leaves, so the floors drawn can be checked against it: nothing
//! is lost silently (slivers under [`MIN_PIECE_AREA`] are dropped, and counted).

use super::footprint::{Footprint, FootprintRing, NodeKey};
use geo::{Area, BooleanOps, BoundingRect, Coord, LineString, MultiPolygon, Polygon, Rect};
use std::borrow::Cow;

/// Pieces of outline left over by parts smaller than this (m²) are slivers, not rooms.
pub const MIN_PIECE_AREA: f64 = 1.0;

/// Most times one polygon is split where its rings touch (each split halves it).
const MAX_SPLITS: u32 = 16;

/// Coordinates this close (m) are one point of a cut.
const SNAP: f64 = 1e-5;

/// A footprint cut into pieces.
#[derive(Debug, Clone, Default)]
pub struct Pieces<'f> {
    pub footprints: Vec<Cow<'f, Footprint>>,
    /// The area the cut leaves (m²): what the pieces' floors must cover.
    pub area: f64,
    /// Whether a piece was split where its rings touched.
    pub split: bool,
}

impl<'f> Pieces<'f> {
    /// The footprint whole.
    pub fn whole(footprint: &'f Footprint) -> Self {
        Self {
            area: footprint.area(),
            footprints: vec![Cow::Borrowed(footprint)],
            split: false,
        }
    }

    /// Adds the pieces of another cut.
    pub fn extend(&mut self, other: Pieces<'f>) {
        self.footprints.extend(other.footprints);
        self.area += other.area;
        self.split |= other.split;
    }
}

/// The footprint minus the parts standing in it and the courtyards set apart from it.
pub fn cut_out<'f>(
    footprint: &Footprint,
    parts: &[&Footprint],
    courtyards: &[FootprintRing],
) -> Pieces<'f> {
    // One at a time: parts may overlap (a tower standing on its podium), and overlapping
    // members of one MultiPolygon would cancel out under the even-odd rule.
    let mut rest = MultiPolygon::new(vec![to_polygon(footprint)]);
    let yards: Vec<Polygon<f64>> = courtyards
        .iter()
        .map(|r| Polygon::new(line(r), vec![]))
        .collect();
    for cut in parts.iter().map(|p| to_polygon(p)).chain(yards) {
        if rest.0.is_empty() {
            break;
        }
        rest = rest.difference(&cut);
    }
    let mut sources: Vec<&FootprintRing> = footprint.rings().collect();
    sources.extend(parts.iter().flat_map(|p| p.rings()));
    sources.extend(courtyards);
    from_multipolygon(rest, &sources)
}

/// The footprint cut to the box `lo`..`hi` (local metres); whole when it lies inside.
pub fn truncate<'f>(footprint: Cow<'f, Footprint>, lo: [f64; 2], hi: [f64; 2]) -> Pieces<'f> {
    let points = &footprint.outer.points;
    if points
        .iter()
        .all(|p| p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1])
    {
        return Pieces {
            area: footprint.area(),
            footprints: vec![footprint],
            split: false,
        };
    }
    let outside = points.iter().all(|p| p[0] < lo[0])
        || points.iter().all(|p| p[0] > hi[0])
        || points.iter().all(|p| p[1] < lo[1])
        || points.iter().all(|p| p[1] > hi[1]);
    if outside {
        return Pieces::default();
    }
    let rect = Rect::new(Coord { x: lo[0], y: lo[1] }, Coord { x: hi[0], y: hi[1] });
    let cut = to_polygon(&footprint).intersection(&rect.to_polygon());
    let sources: Vec<&FootprintRing> = footprint.rings().collect();
    from_multipolygon(cut, &sources)
}

fn line(r: &FootprintRing) -> LineString<f64> {
    LineString::new(
        r.points
            .iter()
            .map(|p| Coord { x: p[0], y: p[1] })
            .collect(),
    )
}

fn to_polygon(f: &Footprint) -> Polygon<f64> {
    Polygon::new(line(&f.outer), f.holes.iter().map(line).collect())
}

/// Boolean results in footprints again, each point snapped back to the input point it came from
/// (so it keeps its node key and exact coordinates); a new point gets a coordinate key, the same
/// in every piece that has it.
fn from_multipolygon<'f>(mp: MultiPolygon<f64>, sources: &[&FootprintRing]) -> Pieces<'f> {
    let mut known: Vec<([f64; 2], NodeKey)> = sources
        .iter()
        .flat_map(|r| r.points.iter().copied().zip(r.keys.iter().copied()))
        .collect();
    let mut snap = |c: &Coord<f64>| -> ([f64; 2], NodeKey) {
        let p = [c.x, c.y];
        if let Some(&k) = known
            .iter()
            .find(|(q, _)| (q[0] - p[0]).abs() < SNAP && (q[1] - p[1]).abs() < SNAP)
        {
            return k;
        }
        known.push((p, NodeKey::at(p)));
        (p, NodeKey::at(p))
    };
    let mut ring = |ls: &LineString<f64>| {
        let mut coords: Vec<&Coord<f64>> = ls.0.iter().collect();
        if coords.len() > 1 && coords.first() == coords.last() {
            coords.pop();
        }
        let (points, keys): (Vec<_>, Vec<_>) = coords.into_iter().map(&mut snap).unzip();
        FootprintRing::new(points, keys)
    };
    let mut pieces = Pieces {
        area: mp.unsigned_area(),
        ..Pieces::default()
    };
    let mut simple = Vec::with_capacity(mp.0.len());
    for poly in mp.0 {
        pieces.split |= split_where_rings_touch(poly, MAX_SPLITS, &mut simple);
    }
    for poly in &simple {
        let Ok(f) = Footprint::new(
            ring(poly.exterior()),
            poly.interiors().iter().map(&mut ring).collect(),
        ) else {
            continue;
        };
        if f.area() >= MIN_PIECE_AREA {
            pieces.footprints.push(Cow::Owned(f));
        }
    }
    pieces
}

/// Adds `poly` to `out` as simple polygons: one whose courtyard touches its outline or another
/// courtyard is cut in two by a vertical line through that courtyard, which leaves the
/// courtyard as a bay of each half, and the halves are split again where they still touch.
/// Answers whether it split.
fn split_where_rings_touch(poly: Polygon<f64>, splits: u32, out: &mut Vec<Polygon<f64>>) -> bool {
    let rings = |p: &Polygon<f64>| {
        let open = |ls: &LineString<f64>| {
            let mut pts: Vec<[f64; 2]> = ls.0.iter().map(|c| [c.x, c.y]).collect();
            if pts.len() > 1 && pts.first() == pts.last() {
                pts.pop();
            }
            FootprintRing::from_points(pts)
        };
        (open(p.exterior()), p.interiors().iter().map(open).collect())
    };
    let (outer, holes) = rings(&poly);
    let touching = match Footprint::with_courtyards_apart(outer, holes) {
        Ok((_, apart)) => apart.into_iter().next(),
        Err(_) => None,
    };
    let (Some(yard), true) = (touching, splits > 0) else {
        out.push(poly);
        return false;
    };
    let (Some(whole), Some(bay)) = (
        poly.bounding_rect(),
        Polygon::new(line(&yard), vec![]).bounding_rect(),
    ) else {
        out.push(poly);
        return false;
    };
    let x = (bay.min().x + bay.max().x) / 2.0;
    let (lo, hi) = (whole.min(), whole.max());
    let left = Rect::new(
        Coord {
            x: lo.x - 1.0,
            y: lo.y - 1.0,
        },
        Coord { x, y: hi.y + 1.0 },
    );
    let right = Rect::new(
        Coord { x, y: lo.y - 1.0 },
        Coord {
            x: hi.x + 1.0,
            y: hi.y + 1.0,
        },
    );
    for half in [left, right] {
        for p in poly.intersection(&half.to_polygon()).0 {
            split_where_rings_touch(p, splits - 1, out);
        }
    }
    true
}

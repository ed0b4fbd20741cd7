//! Turning procedural footprints into the building records OSM input produces: coordinates in
//! lon/lat around the city's origin, OSM-style tags, and sequential way ids. Points placed at the
//! same metres are the same lon/lat to the bit, so neighbours that share a wall share its nodes.

use super::params::ProceduralParams;
use crate::building::roof::RoofShape;
use crate::geo::LocalFrame;
use crate::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// An axis-aligned rectangle in metres (east, north) around the city's origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
}

impl Rect {
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }
    pub fn height(&self) -> f64 {
        self.y1 - self.y0
    }
    /// The rectangle shrunk by `d` on every side.
    pub fn inset(&self, d: f64) -> Rect {
        Rect {
            x0: self.x0 + d,
            y0: self.y0 + d,
            x1: self.x1 - d,
            y1: self.y1 - d,
        }
    }
    /// Counter-clockwise corners.
    pub fn ring(&self) -> Vec<[f64; 2]> {
        vec![
            [self.x0, self.y0],
            [self.x1, self.y0],
            [self.x1, self.y1],
            [self.x0, self.y1],
        ]
    }
}

/// Picks an index with probability proportional to its weight; `None` when all are zero (or the
/// weights do not sum to a finite number, which [`super::ProceduralParams::validate`] refuses).
pub fn weighted(rng: &mut ChaCha8Rng, weights: &[f64]) -> Option<usize> {
    let total: f64 = weights.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return None;
    }
    let mut pick = rng.random_range(0.0..total);
    for (i, &w) in weights.iter().enumerate() {
        if pick < w {
            return Some(i);
        }
        pick -= w;
    }
    weights.iter().rposition(|&w| w > 0.0)
}

const FACADES: [&str; 8] = [
    "#e8dcc8", "#d9c6a5", "#f0e6d2", "#c9b8a0", "#d8d0c0", "#b86f52", "#e4d4b4", "#cfc8bd",
];
const PITCHED_ROOFS: [&str; 5] = ["#8b3a2a", "#7a4030", "#a0522d", "#5a5a5a", "#3f4a55"];
const FLAT_ROOFS: [&str; 3] = ["#8c8c8c", "#a0a0a0", "#6e6e6e"];

pub struct Builder<'a> {
    frame: LocalFrame,
    params: &'a ProceduralParams,
    pub rng: ChaCha8Rng,
    pub records: Vec<BuildingRecord>,
}

impl<'a> Builder<'a> {
    pub fn new(params: &'a ProceduralParams, rng: ChaCha8Rng) -> Self {
        Self {
            frame: LocalFrame::new(params.lon, params.lat, 0.0),
            params,
            rng,
            records: Vec::new(),
        }
    }

    fn ring(&self, points: &[[f64; 2]]) -> Ring {
        Ring {
            nodes: points
                .iter()
                .map(|p| {
                    let (lon, lat, _) = self.frame.to_geographic([p[0], p[1], 0.0]);
                    RingNode { id: None, lon, lat }
                })
                .collect(),
        }
    }

    /// Adds a building or part; `tags` are OSM-style.
    pub fn add(
        &mut self,
        outer: &[[f64; 2]],
        holes: &[Vec<[f64; 2]>],
        is_part: bool,
        tags: Vec<(&str, String)>,
    ) {
        let id = OsmId::Way(self.records.len() as i64 + 1);
        let tags: Tags = tags.into_iter().map(|(k, v)| (k.to_owned(), v)).collect();
        let outers = vec![self.ring(outer)];
        let inners = holes.iter().map(|h| self.ring(h)).collect();
        self.records.push(BuildingRecord {
            id,
            is_part,
            outers,
            inners,
            tags,
        });
    }

    /// A roof shape from the weights; flat when every weight is zero.
    pub fn roof_shape(&mut self) -> RoofShape {
        weighted(&mut self.rng, &self.params.roofs).map_or(RoofShape::Flat, |i| RoofShape::ALL[i])
    }

    pub fn between(&mut self, lo: f64, hi: f64) -> f64 {
        self.rng.random_range(lo..hi)
    }

    /// A whole number of levels in `lo..=hi`.
    pub fn rng_levels(&mut self, lo: u32, hi: u32) -> u32 {
        self.rng.random_range(lo..=hi)
    }

    /// Rounded to centimetres, as a tag value.
    pub fn metres(v: f64) -> String {
        format!("{:.2}", v)
    }

    fn pick<'s>(&mut self, list: &[&'s str]) -> &'s str {
        list[self.rng.random_range(0..list.len())]
    }

    /// The common tags of a building: type, height, levels, roof shape and height, colours.
    /// `short` is the footprint's shorter side, for a plausible roof height.
    pub fn tags(
        &mut self,
        layout: &str,
        building: &str,
        levels: u32,
        shape: RoofShape,
        short: f64,
    ) -> Vec<(&'static str, String)> {
        let walls = f64::from(levels) * 3.0;
        let roof = match shape {
            RoofShape::Flat => 0.0,
            RoofShape::Skillion => self.between(1.5, 3.0),
            _ => short / 2.0 * self.between(0.55, 1.0),
        };
        let mut t = vec![
            ("building", building.to_owned()),
            ("building:levels", levels.to_string()),
            ("height", Self::metres(walls + roof)),
            ("roof:shape", shape.tag().to_owned()),
            ("building:colour", self.pick(&FACADES).to_owned()),
            ("citymesh:layout", layout.to_owned()),
        ];
        if shape == RoofShape::Flat {
            t.push(("roof:colour", self.pick(&FLAT_ROOFS).to_owned()));
        } else {
            t.push(("roof:height", Self::metres(roof)));
            t.push(("roof:colour", self.pick(&PITCHED_ROOFS).to_owned()));
        }
        if shape == RoofShape::Skillion {
            let d = self.rng.random_range(0..8u32) * 45;
            t.push(("roof:direction", d.to_string()));
        }
        t
    }
}

//! Procedural cities (docs/method.md section 10): a seeded, deterministic generator that splits an
//! area into about 2^n blocks by recursive subdivision, with streets between them, fills each
//! block with a layout picked by weight (detached houses, row houses, perimeter blocks, towers
//! with parts, industrial halls) and roofs picked by weight, and emits the same building records
//! OSM input produces, so the same generator builds them.

mod builder;
mod layout;
mod params;

pub use builder::Rect;
pub use params::{
    DEFAULT_LAT, DEFAULT_LON, LayoutType, MAX_COMPLEXITY, MAX_SIDE, MIN_SIDE, ParamError,
    ProceduralParams,
};

use crate::geo::{GeoBbox, LocalFrame};
use crate::osm::BuildingRecord;
use builder::{Builder, weighted};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A generated city: its buildings and the area they stand in.
#[derive(Debug, Clone, PartialEq)]
pub struct ProceduralCity {
    pub records: Vec<BuildingRecord>,
    pub bbox: GeoBbox,
}

/// Splits `rect` `depth` more times along its longer side, leaving a street in each cut; streets
/// are wider near the top of the hierarchy.
fn subdivide(rect: Rect, depth: u32, level: u32, rng: &mut ChaCha8Rng, out: &mut Vec<Rect>) {
    let street = (22.0 - 3.0 * f64::from(level)).max(8.0);
    let long = rect.width().max(rect.height());
    if depth == 0 || long < 2.0 * 22.0 + street {
        out.push(rect);
        return;
    }
    let t = rng.random_range(0.35..0.65);
    let (a, b) = if rect.width() >= rect.height() {
        let cut = rect.x0 + rect.width() * t;
        (
            Rect {
                x1: cut - street / 2.0,
                ..rect
            },
            Rect {
                x0: cut + street / 2.0,
                ..rect
            },
        )
    } else {
        let cut = rect.y0 + rect.height() * t;
        (
            Rect {
                y1: cut - street / 2.0,
                ..rect
            },
            Rect {
                y0: cut + street / 2.0,
                ..rect
            },
        )
    };
    subdivide(a, depth - 1, level + 1, rng, out);
    subdivide(b, depth - 1, level + 1, rng, out);
}

/// Generates the city the parameters describe.
///
/// ```
/// use citymesh_core::procedural::{ProceduralParams, generate_city};
/// let city = generate_city(&ProceduralParams::default()).unwrap();
/// assert!(city.records.len() > 100);
/// assert_eq!(city, generate_city(&ProceduralParams::default()).unwrap());
/// ```
pub fn generate_city(params: &ProceduralParams) -> Result<ProceduralCity, ParamError> {
    params.validate()?;
    let mut b = Builder::new(params, ChaCha8Rng::seed_from_u64(params.seed));
    let (hw, hh) = (params.width / 2.0, params.height / 2.0);
    let area = Rect {
        x0: -hw,
        y0: -hh,
        x1: hw,
        y1: hh,
    };
    let mut blocks = Vec::new();
    subdivide(area, params.complexity, 0, &mut b.rng, &mut blocks);
    for block in blocks {
        // Only layouts with weight that fit the block; a block nothing fits stays a park.
        let fits = |l: LayoutType| block.width().min(block.height()) >= l.min_block();
        let weights: Vec<f64> = LayoutType::ALL
            .iter()
            .zip(params.layouts)
            .map(|(l, w)| if fits(*l) { w } else { 0.0 })
            .collect();
        if let Some(i) = weighted(&mut b.rng, &weights) {
            layout::place(LayoutType::ALL[i], &mut b, block);
        }
    }
    let frame = LocalFrame::new(params.lon, params.lat, 0.0);
    let (w, s, _) = frame.to_geographic([-hw, -hh, 0.0]);
    let (e, n, _) = frame.to_geographic([hw, hh, 0.0]);
    let bbox = GeoBbox::new(w, s, e, n).map_err(|_| ParamError::Location {
        lon: params.lon,
        lat: params.lat,
    })?;
    Ok(ProceduralCity {
        records: b.records,
        bbox,
    })
}

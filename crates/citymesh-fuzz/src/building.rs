//! The building target: arbitrary outlines (star-shaped or anything at all, with or without a
//! courtyard) with arbitrary tags, through the generator to a mesh that must be closed and face
//! outwards whenever the building is generated at all.

use arbitrary::{Result, Unstructured};
use citymesh_core::geo::GeoBbox;
use citymesh_core::mesh::check_closed;
use citymesh_core::osm::{BuildingRecord, OsmId, Ring, RingNode, Tags};
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::ElevationModel;

const SHAPES: [&str; 11] = [
    "flat",
    "gabled",
    "hipped",
    "pyramidal",
    "skillion",
    "half-hipped",
    "gambrel",
    "mansard",
    "dome",
    "",
    "GABLED",
];
const NUMBERS: [&str; 12] = [
    "10", "3.5", "0", "-4", "1e9", "NaN", "inf", "12 m", "40'", "tall", "0.001", "250",
];

fn pick<'a>(u: &mut Unstructured<'_>, from: &[&'a str]) -> Result<&'a str> {
    Ok(from[u.choose_index(from.len())?])
}

/// A ring of `n` points around `(cx, cy)` metres: star-shaped (angles in order) or free.
fn ring(u: &mut Unstructured<'_>, id_base: i64, scale: f64) -> Result<Ring> {
    let n = u.int_in_range(3..=24)?;
    let star = u.ratio(3, 4)?;
    let mut pts = Vec::with_capacity(n + 1);
    for i in 0..n {
        let (x, y) = if star {
            let r = scale * (0.3 + f64::from(u.int_in_range(0..=100u8)?) / 100.0);
            let t = (i as f64 + f64::from(u.int_in_range(0..=90u8)?) / 100.0) / n as f64
                * std::f64::consts::TAU;
            (r * t.cos(), r * t.sin())
        } else {
            let q = |v: i8| f64::from(v) / 127.0 * scale;
            (q(u.arbitrary()?), q(u.arbitrary()?))
        };
        pts.push(RingNode {
            id: Some(id_base + i as i64),
            lon: 8.4 + x / 73_000.0,
            lat: 49.0 + y / 111_000.0,
        });
    }
    pts.push(pts[0]);
    Ok(Ring { nodes: pts })
}

fn record(u: &mut Unstructured<'_>) -> Result<BuildingRecord> {
    let outer = ring(u, 1, 20.0)?;
    let inners = if u.ratio(1, 4)? {
        vec![ring(u, 1000, 5.0)?]
    } else {
        Vec::new()
    };
    let mut tags = Tags::new();
    tags.insert("building".into(), "yes".into());
    for (key, values) in [
        ("height", &NUMBERS[..]),
        ("min_height", &NUMBERS[..]),
        ("roof:height", &NUMBERS[..]),
        ("building:levels", &NUMBERS[..]),
        ("roof:levels", &NUMBERS[..]),
        ("roof:direction", &["0", "45", "NE", "370", "-90", "x"][..]),
        ("roof:orientation", &["along", "across", "diagonal"][..]),
        ("roof:shape", &SHAPES[..]),
    ] {
        if u.arbitrary()? {
            tags.insert(key.into(), pick(u, values)?.into());
        }
    }
    Ok(BuildingRecord {
        id: OsmId::Way(7),
        is_part: false,
        outers: vec![outer],
        inners,
        tags,
    })
}

/// The building `bytes` describe, if they describe one (to look at a saved failure).
pub fn decode_building(bytes: &[u8]) -> Option<BuildingRecord> {
    record(&mut Unstructured::new(bytes)).ok()
}

/// Generates one arbitrary building; panics when its mesh is generated but not closed.
pub fn building(bytes: &[u8]) {
    let Some(record) = decode_building(bytes) else {
        return;
    };
    let Ok(bbox) = GeoBbox::new(8.399, 48.999, 8.401, 49.001) else {
        return;
    };
    let scene = Scene::new(
        &ElevationModel::default(),
        &bbox,
        &[vec![&record]],
        Border::Whole,
    );
    if scene.buildings.generated == 1 {
        let report = check_closed(&scene.mesh, scene.cluster_triangles[0].clone());
        assert!(report.is_closed_and_outward(), "not closed: {report:?}");
    }
    let _ = scene.to_glb();
}

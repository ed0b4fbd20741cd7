//! The targets: the OSM readers (PBF, XML, Overpass JSON), the GeoJSON reader, the HGT parser
//! with the ground it builds, the text parsers of request parameters and tags, the building
//! generator through to a closed mesh, and labelled roof footprints and classifier heads.

use citymesh_core::building::set::BuildingSet;
use citymesh_core::building::tags::{
    parse_angle, parse_colour, parse_direction, parse_length, parse_levels,
};
use citymesh_core::geo::{GeoBbox, TileCoord, parse_wkt_polygon};
use citymesh_core::geojson::{GeoJsonLimits, read_geojson};
use citymesh_core::learn::SoftmaxRegression;
use citymesh_core::osm::read_buildings;
use citymesh_core::scene::{Border, Scene};
use citymesh_core::terrain::{ElevationModel, HgtTile};
use std::sync::Arc;

/// One fuzz target: its name and the function that must not panic on any bytes.
#[derive(Clone, Copy)]
pub struct Target {
    pub name: &'static str,
    pub run: fn(&[u8]),
    /// Real inputs (file names under the data folder's `osm/` or `dem/`) to mutate.
    pub seeds: &'static [&'static str],
    /// Small inputs of the right shape to mutate besides.
    pub inline: &'static [&'static str],
}

const GEOJSON_SEED: &str = r#"{"type": "FeatureCollection", "bbox": [8.4, 49.0, 8.401, 49.001], "features": [
{"type": "Feature", "properties": {"building": "yes", "height": 12, "roof:shape": "gabled", "roof:height": 3},
 "geometry": {"type": "Polygon", "coordinates": [[[8.4001, 49.0001], [8.4005, 49.0001], [8.4005, 49.0004], [8.4001, 49.0004], [8.4001, 49.0001]]]}},
{"type": "Feature", "properties": {"building:part": "yes", "min_height": 4, "building:levels": "3", "roof:shape": "hipped"},
 "geometry": {"type": "MultiPolygon", "coordinates": [[[[8.4006, 49.0005], [8.4009, 49.0005], [8.4009, 49.0008], [8.4006, 49.0008], [8.4006, 49.0005]],
 [[8.4007, 49.0006], [8.40075, 49.00065], [8.40072, 49.0007], [8.4007, 49.0006]]]]}}]}"#;

/// A building with courtyards (three, each a small square).
const HOLES_SEED: &str = r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "id": 7,
 "properties": {"building": "yes", "height": 12, "roof:shape": "hipped"},
 "geometry": {"type": "Polygon", "coordinates": [[[8.4000, 49.0000], [8.4010, 49.0000], [8.4010, 49.0006], [8.4000, 49.0006], [8.4000, 49.0000]],
 [[8.4001, 49.0001], [8.4001, 49.0002], [8.4002, 49.0002], [8.4002, 49.0001], [8.4001, 49.0001]],
 [[8.4004, 49.0001], [8.4004, 49.0002], [8.4005, 49.0002], [8.4005, 49.0001], [8.4004, 49.0001]],
 [[8.4007, 49.0003], [8.4007, 49.0004], [8.4008, 49.0004], [8.4008, 49.0003], [8.4007, 49.0003]]]}}]}"#;

/// Every target.
pub const TARGETS: [Target; 11] = [
    Target {
        name: "osm_pbf",
        run: osm,
        seeds: &["osm/tram-junction.osm.pbf"],
        inline: &[],
    },
    Target {
        name: "osm_xml",
        run: osm,
        seeds: &["osm/nuremberg-laufamholz.osm"],
        inline: &[],
    },
    Target {
        name: "osm_json",
        run: osm,
        seeds: &["osm/karlsruhe-kirchfeld.overpass.json"],
        inline: &[],
    },
    Target {
        name: "geojson",
        run: geojson,
        seeds: &[],
        inline: &[GEOJSON_SEED],
    },
    Target {
        name: "geojson_scene",
        run: geojson_scene,
        seeds: &[],
        inline: &[HOLES_SEED, GEOJSON_SEED],
    },
    Target {
        name: "http",
        run: super::http::requests,
        seeds: &[],
        inline: &[
            "\u{0}0123456789abcdef0123456789abcdef",
            "\u{2}{\"bbox\": [8.4, 49.0, 8.401, 49.001]}",
            "\u{2}{\"type\": \"FeatureCollection\", \"features\": [{\"type\": \"Feature\", \"properties\": {\"osm_id\": \"way/1\"}, \"geometry\": {\"type\": \"Point\", \"coordinates\": [8.4, 49.0]}}]}",
            "\u{3}{\"bbox\": \"8.4,49.0,8.401,49.001\"}",
            "\u{4}model/gltf-binary;q=0.5, application/json;q=0.9, */*;q=0.1",
            "\u{5}0123456789abcdef0123456789abcdef",
            "\u{6}0123456789abcdef0123456789abcdef",
        ],
    },
    Target {
        name: "import",
        run: super::import::import,
        seeds: &[],
        inline: &[
            r#"{"elements":[{"type":"node","id":1,"lat":49.01,"lon":8.4},{"type":"node","id":2,"lat":49.01,"lon":8.4002},{"type":"node","id":3,"lat":49.0102,"lon":10.4002},{"type":"node","id":4,"lat":49.0102,"lon":8.4},{"type":"way","id":77,"nodes":[1,2,3,4,1],"tags":{"building":"yes"}}]}"#,
            r#"<osm version="0.6"><node id="1" lat="49.01" lon="8.4"/><node id="2" lat="49.01" lon="8.4002"/><node id="3" lat="49.0102" lon="8.4002"/><node id="3" lat="52.0102" lon="8.4002"/><node id="4" lat="49.0102" lon="8.4"/><way id="77"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="building" v="yes"/></way></osm>"#,
        ],
    },
    Target {
        name: "hgt",
        run: hgt,
        seeds: &[],
        inline: &[],
    },
    Target {
        name: "params",
        run: params,
        seeds: &[],
        inline: &[
            "8.39,49.04,8.41,49.06",
            "16/34297/22502",
            "12 m;3;NE;#ff0000;45",
        ],
    },
    Target {
        name: "building",
        run: super::building::building,
        seeds: &[],
        inline: &[],
    },
    Target {
        name: "roof_labels",
        run: roof_labels,
        seeds: &[],
        inline: &[
            "POLYGON ((366 0.39, 365.6 291, 42.1 290.6, 0 97.6, 42.5 0, 366 0.39), (1 1, 2 1, 2 2, 1 1))",
            r#"{"classes":3,"dims":2,"mean":[0.5,1],"scale":[2,0.25],"weights":[1,-1,0,2,-3,0.5],"bias":[0,0.1,-0.1]}"#,
        ],
    },
];

/// The target of a name.
pub fn find(name: &str) -> Option<Target> {
    TARGETS.iter().copied().find(|t| t.name == name)
}

/// Any OSM input: read, then indexed as the server indexes it.
fn osm(bytes: &[u8]) {
    if let Ok(b) = read_buildings(bytes) {
        let set = BuildingSet::new(b.buildings);
        let _ = set.extent();
    }
}

fn geojson(bytes: &[u8]) {
    let limits = GeoJsonLimits {
        max_features: 200,
        max_vertices: 20_000,
    };
    if let Ok(scene) = read_geojson(bytes, limits) {
        let set = BuildingSet::new(scene.records);
        let _ = set.groups();
    }
}

/// GeoJSON read and generated (courtyards and all) on flat ground: the mesh stays finite.
fn geojson_scene(bytes: &[u8]) {
    let limits = GeoJsonLimits {
        max_features: 50,
        max_vertices: 5_000,
    };
    let Ok(scene) = read_geojson(bytes, limits) else {
        return;
    };
    let Some(bbox) = scene
        .bbox
        .or_else(|| GeoBbox::new(8.39, 48.99, 8.41, 49.01).ok())
    else {
        return;
    };
    let set = BuildingSet::new(scene.records);
    let model = ElevationModel::default();
    let built = Scene::new(&model, &bbox, &set.groups(), Border::Whole);
    assert!(
        built.mesh.positions.iter().flatten().all(|c| c.is_finite()),
        "a non-finite position"
    );
}

/// HGT bytes of any length; a tile of the right size (its samples taken from the input, cycled)
/// becomes an elevation model whose ground is built over a small box.
fn hgt(bytes: &[u8]) {
    let _ = HgtTile::from_bytes(49, 8, bytes);
    if bytes.len() < 2 {
        return;
    }
    let mut full = Vec::with_capacity(2_884_802);
    while full.len() < 2_884_802 {
        let take = (2_884_802 - full.len()).min(bytes.len());
        full.extend_from_slice(&bytes[..take]);
    }
    let Ok(tile) = HgtTile::from_bytes(49, 8, &full) else {
        return;
    };
    let model = ElevationModel::new(vec![Arc::new(tile)]);
    let x = f64::from(bytes[0]) / 256.0;
    if let Ok(bbox) = GeoBbox::new(
        8.0 + x * 0.9,
        49.0 + x * 0.9,
        8.01 + x * 0.9,
        49.01 + x * 0.9,
    ) {
        let scene = Scene::ground(&model, &bbox);
        assert!(
            scene.mesh.positions.iter().flatten().all(|c| c.is_finite()),
            "ground with a non-finite position"
        );
        let _ = scene.to_glb();
    }
}

/// What a labelled roof set and a roof-classifier head file hold: a footprint in WKT, and a
/// head's regression as JSON, run on a row made from the input.
fn roof_labels(bytes: &[u8]) {
    let text = String::from_utf8_lossy(bytes);
    if let Ok(rings) = parse_wkt_polygon(&text, 10_000) {
        assert!(rings.iter().all(|r| r.len() >= 3));
        assert!(
            rings
                .iter()
                .flatten()
                .all(|p| p[0].is_finite() && p[1].is_finite())
        );
    }
    if let Ok(model) = serde_json::from_slice::<SoftmaxRegression>(bytes) {
        let row: Vec<f32> = (0..model.dims.min(4096))
            .map(|i| f32::from(bytes[i % bytes.len().max(1)]))
            .collect();
        if let Some(p) = model.probabilities(&row) {
            assert_eq!(p.len(), model.classes);
        }
    }
}

/// The text parsers a request or a tag reaches: boxes, tile paths, lengths, levels, angles,
/// directions, colours.
fn params(bytes: &[u8]) {
    let text = String::from_utf8_lossy(bytes);
    let _ = text.parse::<GeoBbox>();
    let mut parts = text.splitn(3, '/');
    let mut number = || parts.next().and_then(|p| p.parse::<u32>().ok());
    if let (Some(z), Some(x), Some(y)) = (number(), number(), number())
        && let Ok(t) = TileCoord::new(z, x, y)
    {
        let b = t.bounds();
        assert!(b.contains(b.center().0, b.center().1));
    }
    for value in text.split(';') {
        let _ = parse_length(value);
        let _ = parse_levels(value);
        let _ = parse_angle(value);
        let _ = parse_direction(value);
        let _ = parse_colour(value);
    }
}

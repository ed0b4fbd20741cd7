//! Building records as a GeoJSON FeatureCollection (RFC 7946): one Feature per record, its OSM
//! tags as string properties, its id (`way/12`) as the Feature id, and the area as `bbox`.

use crate::geo::GeoBbox;
use crate::osm::{BuildingRecord, Ring};
use serde_json::{Value, json};

fn ring(r: &Ring) -> Value {
    let mut coords: Vec<Value> = r.nodes.iter().map(|n| json!([n.lon, n.lat])).collect();
    if let Some(first) = coords.first().cloned() {
        coords.push(first);
    }
    Value::Array(coords)
}

/// The records as GeoJSON bytes. `bbox` becomes the collection's `bbox` member, which
/// `POST /scene.glb` uses as the scene's extent.
pub fn write_geojson(records: &[BuildingRecord], bbox: &GeoBbox) -> Vec<u8> {
    let features: Vec<Value> = records
        .iter()
        .map(|r| {
            let geometry = if r.outers.len() == 1 {
                let mut rings = vec![ring(&r.outers[0])];
                rings.extend(r.inners.iter().map(ring));
                json!({"type": "Polygon", "coordinates": rings})
            } else {
                // Each outer ring takes the courtyards whose first point it holds.
                let polygons: Vec<Value> = r
                    .outers
                    .iter()
                    .map(|o| {
                        let mut rings = vec![ring(o)];
                        rings.extend(
                            r.inners
                                .iter()
                                .filter(|i| {
                                    i.nodes.first().is_some_and(|p| {
                                        crate::building::cluster::ring_contains(
                                            &o.nodes,
                                            (p.lon, p.lat),
                                        )
                                    })
                                })
                                .map(ring),
                        );
                        Value::Array(rings)
                    })
                    .collect();
                json!({"type": "MultiPolygon", "coordinates": polygons})
            };
            json!({
                "type": "Feature",
                "id": r.id.to_string(),
                "properties": r.tags,
                "geometry": geometry,
            })
        })
        .collect();
    let doc = json!({
        "type": "FeatureCollection",
        "bbox": [bbox.min_lon(), bbox.min_lat(), bbox.max_lon(), bbox.max_lat()],
        "features": features,
    });
    serde_json::to_vec(&doc).unwrap_or_default()
}

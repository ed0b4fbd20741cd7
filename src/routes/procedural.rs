//! `GET /procedural.geojson` and `GET /procedural.glb`: a seeded procedural city, as building
//! definitions (GeoJSON with OSM-style properties) or as the mesh the same generator builds from
//! them (on flat ground, or the DEM where one covers the place).

use super::conditional::{conditional_response, generated_response};
use super::schemas::GlbBytes;
use crate::cache::etag_header;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::Generator;
use crate::pipeline::{Buildings, MeshOptions, generate, run_blocking};
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::Response;
use bytes::Bytes;
use citymesh_core::building::roof::RoofShape;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geojson::write_geojson;
use citymesh_core::mesh::Encoding;
use citymesh_core::procedural::{LayoutType, ProceduralCity, ProceduralParams, generate_city};
use citymesh_core::scene::SceneArea;
use serde::Deserialize;
use std::sync::Arc;
use utoipa::IntoParams;

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct ProceduralQuery {
    /// Seed of the generator (default 1): the same parameters and seed give the same city.
    #[param(minimum = 0)]
    pub seed: Option<i64>,
    /// Size in metres, `W,H` or one number for a square (default `1000,1000`; 50 to 5000 each,
    /// within the server's area limit).
    pub size: Option<String>,
    /// The area is split into about 2^complexity blocks (0 to 12, default 6).
    pub complexity: Option<u32>,
    /// Layout weights, e.g. `detached:3,row:2,perimeter:2,tower:1,industrial:1` (the default);
    /// layouts not named get weight 0.
    pub layouts: Option<String>,
    /// Roof shape weights where the layout does not force flat roofs, e.g. `gabled:1,hipped:1`;
    /// shapes not named get 0. Default `flat:3,gabled:4,hipped:3,pyramidal:1,skillion:1,half-hipped:1,gambrel:1,mansard:1`.
    pub roofs: Option<String>,
    /// Where the city's centre stands (default Karlsruhe palace, 8.4044 E 49.0135 N).
    pub lon: Option<f64>,
    pub lat: Option<f64>,
}

fn bad(detail: String) -> AppError {
    AppError::bad_request("invalid_parameter", detail)
}

/// `name:weight,...` into weights over `names`; names not given get 0.
fn weights<const N: usize>(text: &str, names: [&str; N], what: &str) -> Result<[f64; N], AppError> {
    let mut out = [0.0; N];
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (name, value) = item
            .split_once(':')
            .ok_or_else(|| bad(format!("{what}: '{item}' is not name:weight")))?;
        let i = names
            .iter()
            .position(|n| *n == name.trim())
            .ok_or_else(|| {
                bad(format!(
                    "{what}: unknown '{name}'; known: {}",
                    names.join(", ")
                ))
            })?;
        out[i] = value.trim().parse().map_err(|_| {
            bad(format!(
                "{what}: weight '{value}' of {name} is not a number"
            ))
        })?;
    }
    Ok(out)
}

impl ProceduralQuery {
    pub fn params(&self, max_km2: f64) -> Result<ProceduralParams, AppError> {
        let mut p = ProceduralParams::default();
        if let Some(seed) = self.seed {
            p.seed = u64::try_from(seed)
                .map_err(|_| bad(format!("seed {seed} must be a whole number ≥ 0")))?;
        }
        if let Some(size) = &self.size {
            let v: Vec<f64> = size
                .split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| {
                    bad(format!(
                        "size '{size}' must be W,H or one number, in metres"
                    ))
                })?;
            (p.width, p.height) = match v.as_slice() {
                [s] => (*s, *s),
                [w, h] => (*w, *h),
                _ => return Err(bad(format!("size '{size}' must be W,H or one number"))),
            };
        }
        if let Some(c) = self.complexity {
            p.complexity = c;
        }
        if let Some(l) = &self.layouts {
            p.layouts = weights(
                l,
                LayoutType::ALL.map(citymesh_core::procedural::LayoutType::name),
                "layouts",
            )?;
        }
        if let Some(r) = &self.roofs {
            p.roofs = weights(
                r,
                RoofShape::ALL.map(citymesh_core::building::roof::RoofShape::tag),
                "roofs",
            )?;
        }
        p.lon = self.lon.unwrap_or(p.lon);
        p.lat = self.lat.unwrap_or(p.lat);
        p.validate().map_err(|e| bad(e.to_string()))?;
        let km2 = p.width * p.height / 1e6;
        if km2 > max_km2 {
            return Err(bad(format!(
                "the city covers {km2:.2} km², more than this server's limit of {max_km2} km²"
            )));
        }
        Ok(p)
    }
}

async fn city(
    generator: &Generator,
    query: Result<Query<ProceduralQuery>, QueryRejection>,
) -> Result<ProceduralCity, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let params = query.params(generator.limits.max_bbox_km2)?;
    run_blocking(generator, move || {
        generate_city(&params).map_err(|e| bad(e.to_string()))
    })
    .await
}

/// A procedural city's building definitions as GeoJSON.
///
/// A FeatureCollection whose `bbox` is the city's area and whose features carry OSM-style
/// properties (`building`, `height`, `building:levels`, `roof:shape`, `roof:height`, colours,
/// `building:part`, and `citymesh:layout`). Posting it to `POST /scene.glb` gives the same mesh
/// as `/procedural.glb` with the same parameters.
#[utoipa::path(get, path = "/procedural.geojson", tag = "procedural", params(ProceduralQuery),
    responses(
        (status = 200, description = "The definitions", content_type = "application/geo+json", body = Object),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "A parameter is malformed or out of range", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn procedural_geojson(
    State(generator): State<Generator>,
    request_headers: HeaderMap,
    query: Result<Query<ProceduralQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let city = city(&generator, query).await?;
    let body = Bytes::from(write_geojson(&city.records, &city.bbox));
    let mut headers = HeaderMap::new();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/geo+json"),
    );
    let etag = etag_header(None, &body);
    Ok(conditional_response(
        &request_headers,
        body,
        etag,
        headers,
        "public, max-age=3600",
    ))
}

/// A procedural city as binary glTF.
///
/// The city's buildings, generated by the same generator as OSM data, on the ground of its area
/// (flat at 0 m, or the DEM where one covers it). The headers are those of `/scene.glb`.
#[utoipa::path(get, path = "/procedural.glb", tag = "procedural", params(ProceduralQuery),
    responses(
        (status = 200, description = "The city", content_type = "model/gltf-binary", body = inline(GlbBytes)),
        (status = 304, description = "Not modified: the If-None-Match ETag is current"),
        (status = 400, description = "A parameter is malformed or out of range", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 503, description = "Every generation slot is busy, or generation took too long; see Retry-After", body = ErrorBody),
    ))]
pub async fn procedural_glb(
    State(generator): State<Generator>,
    request_headers: HeaderMap,
    query: Result<Query<ProceduralQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let city = city(&generator, query).await?;
    let bbox = city.bbox;
    let set = run_blocking(&generator, move || {
        Ok(Arc::new(BuildingSet::new(city.records)))
    })
    .await?;
    let generated = generate(
        &generator,
        SceneArea::Given(bbox),
        Buildings::Given(set),
        None,
        MeshOptions::new(&generator, Encoding::Plain),
    )
    .await?;
    Ok(generated_response(
        &request_headers,
        generated,
        "public, max-age=3600",
    ))
}

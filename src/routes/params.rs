//! Query parameters shared by several routes, and their checks.

use crate::error::AppError;
use crate::pipeline::{MeshOptions, RoofsParam};
use crate::state::{AppState, Limits};
use axum::http::{HeaderMap, header};
use citymesh_core::building::{HeightBase, TagProperties};
use citymesh_core::geo::GeoBbox;
use citymesh_core::mesh::Encoding;
use serde::Deserialize;
use utoipa::IntoParams;

/// Which properties each building carries, as asked with `?tags=`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TagsParam {
    /// The named properties only (`osm_id`, `height`, `roof_shape`, Cesium OSM Buildings'
    /// names...): the default.
    #[default]
    Named,
    /// Also `osm_tags`: every OSM tag of the building as one JSON object.
    All,
}

impl From<TagsParam> for TagProperties {
    fn from(t: TagsParam) -> Self {
        match t {
            TagsParam::Named => TagProperties::Named,
            TagsParam::All => TagProperties::All,
        }
    }
}

/// How a GLB stores its vertices, as asked with `?encoding=`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum EncodingParam {
    /// Core glTF, no extension: f32 positions, every glTF reader loads it.
    Plain,
    /// `KHR_mesh_quantization`: u16 positions in a box over the content, i8 normals.
    Quantized,
    /// Quantized and compressed with `EXT_meshopt_compression` (clients need a meshopt
    /// decoder; CesiumJS has one built in, three.js's `MeshoptDecoder` is one line).
    Meshopt,
}

impl From<EncodingParam> for Encoding {
    fn from(e: EncodingParam) -> Self {
        match e {
            EncodingParam::Plain => Encoding::Plain,
            EncodingParam::Quantized => Encoding::Quantized,
            EncodingParam::Meshopt => Encoding::Meshopt,
        }
    }
}

/// The encoding of a response: `?encoding=` if given, else an `encoding` parameter of a
/// `model/gltf-binary` type in `Accept` (`Accept: model/gltf-binary; encoding=meshopt`), else
/// `default`. An unknown name in `Accept` is ignored (a hint, not a demand).
pub fn encoding_for(
    asked: Option<EncodingParam>,
    headers: &HeaderMap,
    default: Encoding,
) -> Encoding {
    if let Some(e) = asked {
        return e.into();
    }
    headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .filter(|range| range.trim_start().starts_with("model/gltf-binary"))
        .flat_map(|range| range.split(';').skip(1))
        .filter_map(|p| p.split_once('='))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("encoding"))
        .and_then(|(_, v)| v.trim().trim_matches('"').parse().ok())
        .unwrap_or(default)
}

/// The area of a scene.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct BboxQuery {
    /// The area as `minLon,minLat,maxLon,maxLat` in WGS84 degrees, e.g. `8.400,49.010,8.409,49.017`
    /// (the demo city). Latitudes within ±85.0511; the area may not exceed the server's limit (25 km²
    /// by default).
    #[param(
        required = true,
        pattern = r"^\s*-?[0-9.eE+-]+\s*(,\s*-?[0-9.eE+-]+\s*){3}$",
        example = "8.400,49.010,8.409,49.017"
    )]
    pub bbox: Option<String>,
    /// Where roof shapes come from: `osm` (tags, else flat; the default, the paper's scene
    /// without computer vision), `classified` (tags, and for untagged buildings the roof
    /// classifier's predictions, combined with the roof prior's; see `POST /classify`) or
    /// `inferred` (tags, and for untagged buildings the roof prior learned from the tagged
    /// buildings around them; no imagery).
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
    /// How the GLB stores vertices: `plain` (the default: f32, no extension), `quantized`
    /// (`KHR_mesh_quantization`) or `meshopt` (also `EXT_meshopt_compression`, the smallest).
    /// Without it, an `encoding` parameter in `Accept: model/gltf-binary; encoding=...` is used.
    #[param(inline)]
    pub encoding: Option<EncodingParam>,
    /// The ground a building's `height` is counted from on a slope: `lowest` (Simple 3D
    /// Buildings; the default unless the server says otherwise) or `highest` (the paper's rule).
    #[param(inline)]
    pub height_base: Option<HeightBaseParam>,
}

/// The ground a building's `height` is counted from, as asked with `?height_base=`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum HeightBaseParam {
    /// The lowest ground along the outline, as OpenStreetMap's Simple 3D Buildings defines
    /// `height` (the default unless the server's `--height-base` says otherwise).
    Lowest,
    /// The highest ground along the outline (the paper's Figure 5 rule): on a slope, buildings
    /// stand taller than tagged by the ground's rise under them.
    Highest,
}

impl From<HeightBaseParam> for HeightBase {
    fn from(h: HeightBaseParam) -> Self {
        match h {
            HeightBaseParam::Lowest => HeightBase::LowestGround,
            HeightBaseParam::Highest => HeightBase::HighestGround,
        }
    }
}

/// How a scene is meshed: `?encoding=` (or the `Accept` hint, else `default`) and
/// `?height_base=` (else the server's `--height-base`).
pub fn mesh_options(
    state: &AppState,
    encoding: Option<EncodingParam>,
    headers: &HeaderMap,
    default: Encoding,
    heights: Option<HeightBaseParam>,
) -> MeshOptions {
    MeshOptions {
        encoding: encoding_for(encoding, headers, default),
        heights: heights_for(state, heights),
        tags: TagProperties::default(),
    }
}

/// The ground heights count from: `?height_base=` if given, else the server's `--height-base`.
pub fn heights_for(state: &AppState, asked: Option<HeightBaseParam>) -> HeightBase {
    asked.map_or(state.generator.height_base, HeightBase::from)
}

/// Where roof shapes come from, and how the GLB is encoded.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct TileQuery {
    /// `osm` (tags, else flat; the default, the paper's scene without computer vision),
    /// `classified` (tags, and for untagged buildings the roof classifier's predictions combined
    /// with the roof prior's: the response's `X-Citymesh-Roofs` says how many are still pending;
    /// see `POST /classify`) or `inferred` (tags, and for untagged buildings the roof prior
    /// learned from the tagged buildings around them: `X-Citymesh-Roofs: inferred, N`).
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
    /// How the GLB stores vertices: `plain` (f32, no extension), `quantized`
    /// (`KHR_mesh_quantization`) or `meshopt` (also `EXT_meshopt_compression`, the smallest).
    /// The default is `plain` for XYZ tiles and `meshopt` for 3D Tiles content; without the
    /// parameter, an `encoding` parameter in `Accept: model/gltf-binary; encoding=...` is used.
    #[param(inline)]
    pub encoding: Option<EncodingParam>,
    /// `all` gives each building one more property, `osm_tags`: every OSM tag of the element
    /// as a JSON object (for apps that style or filter by any tag); `named` (the default)
    /// carries the named properties only.
    #[param(inline)]
    pub tags: Option<TagsParam>,
}

impl TileQuery {
    /// The properties asked for.
    pub fn tags(&self) -> TagProperties {
        self.tags.unwrap_or_default().into()
    }
}

/// The `roofs`, `encoding` and `tags` of a query string (most tile requests have none: nothing to parse
/// then).
pub fn tile_query_of(query: Option<&str>) -> Result<TileQuery, AppError> {
    match query {
        None | Some("") => Ok(TileQuery {
            roofs: None,
            encoding: None,
            tags: None,
        }),
        Some(q) => serde_urlencoded::from_str::<TileQuery>(q).map_err(|e| {
            AppError::bad_request(
                "invalid_query",
                format!(
                    "{e}: roofs is `osm` (the default), `classified` or `inferred`; encoding \
                     is `plain`, `quantized` or `meshopt`; tags is `named` (the default) or `all`"
                ),
            )
        }),
    }
}

/// Checks a `bbox` parameter against the format, the area limit and the ground-cell limit (the
/// ground's cost: a long thin box has a small area but many cells).
pub fn parse_bbox(text: Option<&str>, limits: &Limits) -> Result<GeoBbox, AppError> {
    let max_km2 = limits.max_bbox_km2;
    let text = text.ok_or_else(|| {
        AppError::bad_request(
            "missing_bbox",
            "add ?bbox=minLon,minLat,maxLon,maxLat, e.g. ?bbox=8.400,49.010,8.409,49.017",
        )
    })?;
    let bbox: GeoBbox = text
        .parse()
        .map_err(|e| AppError::bad_request("invalid_bbox", format!("bbox: {e}")))?;
    let area = bbox.area_km2();
    if area > max_km2 {
        return Err(AppError::bad_request(
            "bbox_too_large",
            format!(
                "the bbox covers {area:.2} km², more than this server's limit of {max_km2} km²: request a smaller area or tiles"
            ),
        ));
    }
    let cells = ground_cells(&bbox);
    if cells > limits.max_ground_cells {
        return Err(AppError::bad_request(
            "bbox_too_large",
            format!(
                "the bbox spans {cells} ground cells (1 arc-second), more than this server's limit of {}: request a smaller or squarer area, or tiles",
                limits.max_ground_cells
            ),
        ));
    }
    Ok(bbox)
}

/// Ground cells a box spans on the finest SRTM grid (1 arc-second), edges included.
pub fn ground_cells(bbox: &GeoBbox) -> u64 {
    let side = |degrees: f64| (degrees * 3600.0).ceil() as u64 + 1;
    side(bbox.max_lon() - bbox.min_lon()).saturating_mul(side(bbox.max_lat() - bbox.min_lat()))
}

/// A path's coordinate as a whole number, or 400 `invalid_tile` naming it.
pub fn whole_number(name: &str, text: &str) -> Result<u32, AppError> {
    text.parse::<u32>().map_err(|_| {
        AppError::bad_request(
            "invalid_tile",
            format!("{name} '{text}' is not a whole number"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ground_cells_count_both_sides() {
        let b = GeoBbox::new(8.0, 49.0, 8.01, 49.002).unwrap();
        assert_eq!(ground_cells(&b), 37 * 9);
        let thin = GeoBbox::new(-180.0, 0.0, 180.0, 0.000_005).unwrap();
        assert_eq!(ground_cells(&thin), (1_296_000 + 1) * 2);
    }
}

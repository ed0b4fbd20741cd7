//! Query parameters shared by several routes, and their checks.

use crate::error::AppError;
use crate::pipeline::RoofsParam;
use crate::state::Limits;
use citymesh_core::geo::GeoBbox;
use serde::Deserialize;
use utoipa::IntoParams;

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
    /// without computer vision) or `classified` (tags, and for untagged buildings the roof
    /// classifier's predictions; see `POST /classify`).
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
}

/// Where roof shapes come from.
#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct RoofsQuery {
    /// `osm` (tags, else flat; the default, the paper's scene without computer vision) or
    /// `classified` (tags, and for untagged buildings the roof classifier's predictions: the
    /// response's `X-Citymesh-Roofs` says how many are still pending; see `POST /classify`).
    #[param(inline)]
    pub roofs: Option<RoofsParam>,
}

/// The `roofs` of a query string (most tile requests have none: nothing to parse then).
pub fn roofs_of(query: Option<&str>) -> Result<RoofsParam, AppError> {
    match query {
        None | Some("") => Ok(RoofsParam::default()),
        Some(q) => serde_urlencoded::from_str::<RoofsQuery>(q)
            .map(|r| r.roofs.unwrap_or_default())
            .map_err(|e| {
                AppError::bad_request(
                    "invalid_query",
                    format!("{e}: roofs is `osm` (the default) or `classified`"),
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

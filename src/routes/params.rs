//! Query parameters shared by several routes, and their checks.

use crate::error::AppError;
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
}

/// Checks a `bbox` parameter against the format and the area limit.
pub fn parse_bbox(text: Option<&str>, max_km2: f64) -> Result<GeoBbox, AppError> {
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
    Ok(bbox)
}

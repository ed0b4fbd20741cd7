//! The headers of GLB answers: the content type and the `X-Citymesh-*` figures of a generation.

use crate::generation_stats::GenerationStats;
use crate::source::short_list;
use axum::http::{HeaderMap, HeaderName, HeaderValue, header};

/// The content type of binary glTF.
pub const GLB: &str = "model/gltf-binary";

/// The headers every GLB response carries, with the generation figures when this request
/// generated it.
pub fn glb_headers(stats: Option<&GenerationStats>) -> HeaderMap {
    // Room for these, the ETag and caching headers and CORS's, so the map never grows.
    let mut h = HeaderMap::with_capacity(if stats.is_some() { 24 } else { 10 });
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(GLB));
    // `Accept: model/gltf-binary; encoding=...` can choose the bytes.
    h.insert(header::VARY, HeaderValue::from_static("accept"));
    let Some(s) = stats else { return h };
    let mut put = |name: &'static str, value: String| {
        if let Ok(v) = HeaderValue::from_str(&value) {
            h.insert(HeaderName::from_static(name), v);
        }
    };
    put(
        "x-citymesh-generation-ms",
        format!("{:.3}", s.generation_ms),
    );
    put("x-citymesh-vertices", s.vertices.to_string());
    put("x-citymesh-triangles", s.triangles.to_string());
    put("x-citymesh-void-cells", s.ground.void_cells.to_string());
    let ground = if s.missing_dem.is_empty() {
        "dem".to_owned()
    } else {
        format!("flat-fallback; missing={}", short_list(&s.missing_dem))
    };
    put("x-citymesh-ground", ground);
    put("x-citymesh-osm", s.osm.clone());
    let b = &s.buildings;
    put("x-citymesh-buildings", b.generated.to_string());
    let skipped = if b.skipped.is_empty() {
        "0".to_owned()
    } else {
        let reasons: Vec<String> = b.skipped.iter().map(|(r, n)| format!("{r}={n}")).collect();
        format!("{}; {}", b.total_skipped(), reasons.join(","))
    };
    put("x-citymesh-buildings-skipped", skipped);
    put(
        "x-citymesh-flat-roofs-percent",
        format!("{:.1}", b.flat_roof_percent()),
    );
    put(
        "x-citymesh-roof-shapes-from-tags-percent",
        format!("{:.1}", b.shape_from_tag_percent()),
    );
    h
}

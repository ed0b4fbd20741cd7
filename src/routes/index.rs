//! `GET /`: a small page pointing at what the server offers.

use axum::response::Html;

pub async fn index() -> Html<&'static str> {
    Html(concat!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>citymesh</title></head><body>",
        "<h1>citymesh ",
        env!("CARGO_PKG_VERSION"),
        "</h1>",
        "<p>3D city meshes from OpenStreetMap and SRTM, generated on demand.</p><ul>",
        "<li><a href=\"/docs\">API documentation (Swagger UI)</a> and <a href=\"/openapi.json\">openapi.json</a></li>",
        "<li><a href=\"/scene.glb?bbox=8.39,49.04,8.41,49.06\">/scene.glb?bbox=8.39,49.04,8.41,49.06</a> (a GLB of Karlsruhe-Neureut)</li>",
        "<li><a href=\"/tiles/16/34297/22492.glb\">/tiles/16/34297/22492.glb</a> (an XYZ tile)</li>",
        "<li><a href=\"/procedural.glb\">/procedural.glb</a> and <a href=\"/procedural.geojson\">/procedural.geojson</a>: ",
        "the procedural demo city (1 km x 1 km at Karlsruhe; <code>?seed=2&amp;complexity=7</code> for another), ",
        "the city served when no data is configured</li>",
        "<li><a href=\"/health\">/health</a></li></ul></body></html>"
    ))
}

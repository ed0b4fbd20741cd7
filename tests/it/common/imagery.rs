//! A real imagery server for the classification tests, on 127.0.0.1: `/ortho/{z}/{x}/{y}.png`
//! are tiles citymesh's renderer draws of every Kirchfeld building with the roof shape its tags
//! say (a synthetic orthophoto), `/grey/...` a plain grey tile (cheap, for tests of the job
//! mechanics), and `/missing`, `/garbage`, `/huge`, `/hang` and `/small` bad answers.

use axum::extract::{Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use citymesh_core::geo::{LocalFrame, TileCoord};
use citymesh_core::osm::{BuildingRecord, read_buildings};
use citymesh_core::roof_image::Image;
use citymesh_core::roof_image::render::Camera;
use citymesh_core::roof_image::synthetic::{Palette, render_orthophoto};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

pub struct Orthophoto {
    pub records: Vec<BuildingRecord>,
    pub frame: LocalFrame,
    pub tiles: Mutex<HashMap<(u8, u32, u32), Vec<u8>>>,
    /// Drawn in a style the model was not trained on: blurred, bands rotated and inverted.
    pub styled: bool,
}

/// Another sensor: a 5 x 5 box blur, the bands rotated (green, blue, red) and inverted.
fn restyle(img: &mut Image) {
    let (w, h) = (img.width, img.height);
    let src = img.pixels.clone();
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 3];
            let mut n = 0.0;
            for dy in -2i64..=2 {
                for dx in -2i64..=2 {
                    let (sx, sy) = (x as i64 + dx, y as i64 + dy);
                    if sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h {
                        let p = src[sy as usize * w + sx as usize];
                        for k in 0..3 {
                            sum[k] += p[k];
                        }
                        n += 1.0;
                    }
                }
            }
            // A false-colour negative: what another sensor's bands can look like.
            let v = [sum[1] / n, sum[2] / n, sum[0] / n];
            img.pixels[y * w + x] = std::array::from_fn(|k| (1.0 - v[k]).clamp(0.0, 1.0));
        }
    }
}

fn render_tile(o: &Orthophoto, t: TileCoord) -> Vec<u8> {
    let b = t.bounds();
    let nw = o.frame.to_local(b.min_lon(), b.max_lat(), 0.0);
    let se = o.frame.to_local(b.max_lon(), b.min_lat(), 0.0);
    let camera = Camera {
        top_left: [nw[0], nw[1]],
        metres_per_pixel: (se[0] - nw[0]) / 256.0,
        width: 256,
        height: 256,
        skew: [0.0, 0.0],
    };
    let mut img: Image = render_orthophoto(&o.records, &o.frame, &camera, Palette::Holdout, 11);
    if o.styled {
        restyle(&mut img);
    }
    let rgb: Vec<u8> = img.to_srgb8().iter().flatten().copied().collect();
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        &rgb,
        256,
        256,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    png
}

async fn good(
    State(o): State<Arc<Orthophoto>>,
    Path((z, x, y)): Path<(u8, u32, String)>,
) -> impl IntoResponse {
    let y: u32 = y.trim_end_matches(".png").parse().unwrap();
    if let Some(png) = o.tiles.lock().unwrap().get(&(z, x, y)) {
        return ([(header::CONTENT_TYPE, "image/png")], png.clone()).into_response();
    }
    let t = TileCoord::new(u32::from(z), x, y).unwrap();
    let o2 = o.clone();
    let png = tokio::task::spawn_blocking(move || render_tile(&o2, t))
        .await
        .unwrap();
    o.tiles.lock().unwrap().insert((z, x, y), png.clone());
    ([(header::CONTENT_TYPE, "image/png")], png).into_response()
}

async fn bad(
    Path((kind, _z, _x, _y)): Path<(String, u8, u32, String)>,
) -> axum::response::Response {
    match kind.as_str() {
        "missing" => StatusCode::NOT_FOUND.into_response(),
        "garbage" => (
            [(header::CONTENT_TYPE, "image/png")],
            b"\x89PNG\r\n garbage".to_vec(),
        )
            .into_response(),
        "huge" => {
            // 200 MB announced and streamed: refused at the limit, never held.
            let chunk = bytes::Bytes::from(vec![0u8; 1 << 20]);
            let stream = futures_util::stream::iter(
                (0..200).map(move |_| Ok::<_, std::io::Error>(chunk.clone())),
            );
            (
                [(header::CONTENT_LENGTH, (200u64 << 20).to_string())],
                axum::body::Body::from_stream(stream),
            )
                .into_response()
        }
        "hang" => {
            tokio::time::sleep(std::time::Duration::from_secs(3600)).await;
            StatusCode::OK.into_response()
        }
        "small" => {
            let mut png = Vec::new();
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut png),
                &vec![128u8; 100 * 100 * 3],
                100,
                100,
                image::ExtendedColorType::Rgb8,
            )
            .unwrap();
            ([(header::CONTENT_TYPE, "image/png")], png).into_response()
        }
        _ => StatusCode::BAD_REQUEST.into_response(),
    }
}

fn png_of(rgb: &[u8], side: u32) -> Vec<u8> {
    let mut png = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new(&mut png),
        rgb,
        side,
        side,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    png
}

async fn grey() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "image/png")],
        png_of(&vec![120u8; 256 * 256 * 3], 256),
    )
}

/// A grey tile after a second: imagery as slow as an overloaded service.
async fn slow_grey() -> impl IntoResponse {
    tokio::time::sleep(std::time::Duration::from_secs(1)).await;
    grey().await
}

/// Starts the imagery server; returns its base URL.
pub async fn imagery_server() -> String {
    imagery_server_with_tiles().await.0
}

/// A WMS GetMap in EPSG:3857 whose box is exactly an XYZ tile: that tile of the orthophoto.
async fn wms(
    State(o): State<Arc<Orthophoto>>,
    Query(q): Query<HashMap<String, String>>,
) -> axum::response::Response {
    const HALF: f64 = 20_037_508.342_789_244;
    let b: Vec<f64> = q["BBOX"].split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!((q["WIDTH"].as_str(), q["HEIGHT"].as_str()), ("256", "256"));
    let side = b[2] - b[0];
    let z = (2.0 * HALF / side).log2().round() as u8;
    let x = ((b[0] + HALF) / side).round() as u32;
    let y = ((HALF - b[3]) / side).round() as u32;
    good(State(o), Path((z, x, format!("{y}.png"))))
        .await
        .into_response()
}

/// [`imagery_server`], with the orthophoto whose rendered tiles it keeps (by z, x, y).
pub async fn imagery_server_with_tiles() -> (String, Arc<Orthophoto>) {
    let all = read_buildings(&super::osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
        .unwrap()
        .buildings;
    let o = Arc::new(Orthophoto {
        records: all,
        frame: LocalFrame::new(8.3995, 49.055, 0.0),
        tiles: Mutex::new(HashMap::new()),
        styled: false,
    });
    let app = axum::Router::new()
        .route("/ortho/{z}/{x}/{y}", axum::routing::get(good))
        .route("/wms", axum::routing::get(wms))
        .with_state(o.clone())
        .route("/grey/{z}/{x}/{y}", axum::routing::get(grey))
        .route("/slow/{z}/{x}/{y}", axum::routing::get(slow_grey))
        .route("/{kind}/{z}/{x}/{y}", axum::routing::get(bad));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    (format!("http://{addr}"), o)
}

/// An imagery server drawing `records` (with the roof shapes their tags say) in a style the model
/// was not trained on, at `/styled/{z}/{x}/{y}`; returns its base URL.
pub async fn styled_imagery_server(records: Vec<BuildingRecord>) -> String {
    let o = Arc::new(Orthophoto {
        records,
        frame: LocalFrame::new(8.3995, 49.055, 0.0),
        tiles: Mutex::new(HashMap::new()),
        styled: true,
    });
    let app = axum::Router::new()
        .route("/styled/{z}/{x}/{y}", axum::routing::get(good))
        .with_state(o);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await.unwrap() });
    format!("http://{addr}")
}

/// The arguments of a server of `osm` with the roof classifier on the XYZ imagery `url` (a
/// `{z}/{x}/{y}` template) named `id`, over the database `db`.
pub fn classifying_args(
    db: &std::path::Path,
    osm: &std::path::Path,
    url: &str,
    id: &str,
) -> citymesh::cli::ServeArgs {
    use clap::Parser;
    let dem = super::dem_dir();
    citymesh::cli::ServeArgs::parse_from([
        "serve",
        "--dem-dir",
        dem.to_str().unwrap(),
        "--cache-db",
        db.to_str().unwrap(),
        "--osm",
        osm.to_str().unwrap(),
        "--roof-classifier",
        "--imagery-url",
        url,
        "--imagery-id",
        id,
    ])
}

//! Meshes with roofs as asked (`roofs=osm|classified`): cached tiles and uncached scenes, with
//! `X-Citymesh-Roofs` saying how complete classified roofs are.

use super::conditional::{cached_response, generated_response};
use crate::cache::TileKey;
use crate::error::AppError;
use crate::pipeline::{
    Buildings, Generated, MeshOptions, RoofFigures, RoofsParam, classified_roofs, generate,
};
use crate::state::AppState;
use axum::http::{HeaderMap, HeaderName, HeaderValue};
use axum::response::Response;
use citymesh_core::scene::SceneArea;

/// The header saying how complete classified roofs are.
pub const ROOFS_HEADER: HeaderName = HeaderName::from_static("x-citymesh-roofs");

/// A tile through the tile cache, with roofs as asked.
pub async fn cached_tile(
    state: &AppState,
    request_headers: &HeaderMap,
    key: TileKey,
    roofs: RoofsParam,
    cache_control: &'static str,
) -> Result<Response, AppError> {
    let area = key.tile.area();
    match roofs {
        RoofsParam::Osm => {
            let (cached, level) = state
                .tiles
                .get_or_generate(key, || async {
                    let mesh = MeshOptions::new(state, key.encoding);
                    let g = generate(state, area, Buildings::FromSource, None, mesh).await?;
                    Ok::<_, AppError>((g.glb, g.stats))
                })
                .await?;
            Ok(cached_response(
                request_headers,
                cached,
                level,
                cache_control,
            ))
        }
        RoofsParam::Classified => {
            let plan = classified_roofs(state, area).await?;
            let key = key.with_roofs(plan.source);
            let figures = plan.figures;
            let (cached, level) = state
                .tiles
                .get_or_generate(key, || async {
                    let g = generate(
                        state,
                        area,
                        Buildings::Loaded(plan.buildings),
                        Some(plan.choice),
                        MeshOptions::new(state, key.encoding),
                    )
                    .await?;
                    Ok::<_, AppError>((g.glb, g.stats))
                })
                .await?;
            let mut response = cached_response(request_headers, cached, level, cache_control);
            add_roofs_header(&mut response, &figures);
            Ok(response)
        }
    }
}

/// A scene with roofs as asked, and the roof figures when classified. Box scenes with roofs from
/// tags and heights as the server counts them come from the scene cache when they were made
/// before (classified ones depend on predictions that keep arriving, and are made each time).
pub async fn generate_with_roofs(
    state: &AppState,
    area: SceneArea,
    roofs: RoofsParam,
    mesh: MeshOptions,
) -> Result<(Generated, Option<RoofFigures>), AppError> {
    match roofs {
        RoofsParam::Osm => {
            let bbox = match area {
                SceneArea::Bbox(b) if mesh.heights == state.height_base => b,
                _ => {
                    return Ok((
                        generate(state, area, Buildings::FromSource, None, mesh).await?,
                        None,
                    ));
                }
            };
            let key = TileKey::bbox(bbox).with_encoding(mesh.encoding);
            let (scene, hit) = state
                .tiles
                .scenes
                .get_or_generate(key, || async {
                    let g = generate(state, area, Buildings::FromSource, None, mesh).await?;
                    Ok::<_, AppError>((g.glb, g.stats))
                })
                .await?;
            let generated = Generated {
                glb: scene.glb,
                stats: (*scene.stats).clone(),
                from_cache: hit,
            };
            Ok((generated, None))
        }
        RoofsParam::Classified => {
            let plan = classified_roofs(state, area).await?;
            let generated = generate(
                state,
                area,
                Buildings::Loaded(plan.buildings),
                Some(plan.choice),
                mesh,
            )
            .await?;
            Ok((generated, Some(plan.figures)))
        }
    }
}

/// A generated scene's response, with `X-Citymesh-Roofs` when roofs were classified.
pub fn scene_response(
    request_headers: &HeaderMap,
    (generated, figures): (Generated, Option<RoofFigures>),
    cache_control: &'static str,
) -> Response {
    let mut response = generated_response(request_headers, generated, cache_control);
    if let Some(f) = figures {
        add_roofs_header(&mut response, &f);
    }
    response
}

fn add_roofs_header(response: &mut Response, figures: &RoofFigures) {
    if let Ok(v) = HeaderValue::from_str(&figures.header()) {
        response.headers_mut().insert(ROOFS_HEADER, v);
    }
}

//! Meshes with roofs as asked (`roofs=osm|classified|inferred`): cached tiles and uncached
//! scenes, with `X-Citymesh-Roofs` saying how many roofs were chosen (and, when classified,
//! how many still wait for a prediction).

use super::conditional::{cached_response, generated_response};
use crate::cache::{RoofSource, TileKey};
use crate::error::AppError;
use crate::pipeline::{
    Buildings, Generated, InferredFigures, MeshOptions, RoofFigures, RoofsParam, classified_roofs,
    gather, generate, inferred_roofs,
};
use crate::source::AreaBuildings;
use crate::state::AppState;
use axum::http::{HeaderMap, HeaderName, HeaderValue};
use axum::response::Response;
use citymesh_core::scene::{RoofChoice, SceneArea};
use std::sync::Arc;

/// The header saying how many roofs were chosen.
pub const ROOFS_HEADER: HeaderName = HeaderName::from_static("x-citymesh-roofs");

/// How the roofs of a generated mesh were chosen beyond the tags.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum ChosenRoofs {
    /// Tags only (`roofs=osm`).
    #[default]
    TagsOnly,
    Classified(RoofFigures),
    Inferred(InferredFigures),
}

impl ChosenRoofs {
    /// The `X-Citymesh-Roofs` value: `classified, n`, `partial, n pending` or `inferred, n`.
    fn header(&self) -> Option<String> {
        match self {
            ChosenRoofs::TagsOnly => None,
            ChosenRoofs::Classified(f) => Some(f.header()),
            ChosenRoofs::Inferred(f) => Some(format!("inferred, {}", f.inferred)),
        }
    }
}

/// An area's buildings with the roofs chosen for them, what keys them in the cache, and how.
struct RoofPlan {
    buildings: AreaBuildings,
    choice: Arc<RoofChoice>,
    source: RoofSource,
    chosen: ChosenRoofs,
}

/// The plan for `roofs`: `None` for `osm`, whose tiles take the tags as they are (their key has
/// no roof source, and the cache gathers the buildings only on a miss).
async fn plan(
    state: &AppState,
    area: SceneArea,
    roofs: RoofsParam,
) -> Result<Option<RoofPlan>, AppError> {
    Ok(match roofs {
        RoofsParam::Osm => None,
        RoofsParam::Inferred => {
            let p = inferred_roofs(&state.generator, area).await?;
            Some(RoofPlan {
                buildings: p.buildings,
                choice: p.choice,
                source: p.source,
                chosen: ChosenRoofs::Inferred(p.figures),
            })
        }
        RoofsParam::Classified => {
            let p = classified_roofs(&state.generator, area).await?;
            Some(RoofPlan {
                buildings: p.buildings,
                choice: p.choice,
                source: p.source,
                chosen: ChosenRoofs::Classified(p.figures),
            })
        }
    })
}

/// A tile through the tile cache, with roofs as asked.
pub async fn cached_tile(
    state: &AppState,
    request_headers: &HeaderMap,
    key: TileKey,
    roofs: RoofsParam,
    cache_control: &'static str,
) -> Result<Response, AppError> {
    let area = key.tile.area();
    let Some(plan) = plan(state, area, roofs).await? else {
        // `roofs=osm`, the common case: as lean as a plain cached tile.
        let (cached, level) = state
            .tiles
            .get_or_generate(
                key,
                || gather(&state.generator, area),
                |buildings| async {
                    let mesh = MeshOptions::new(&state.generator, key.encoding).with_tags(key.tags);
                    let g = generate(
                        &state.generator,
                        area,
                        Buildings::Loaded(buildings),
                        None,
                        mesh,
                    )
                    .await?;
                    Ok::<_, AppError>((g.glb, g.stats))
                },
            )
            .await?;
        return cached_response(request_headers, cached, level, cache_control).await;
    };
    let key = key.with_roofs(plan.source);
    let (cached, level) = state
        .tiles
        .get_or_generate(
            key,
            || async { Ok::<_, AppError>(plan.buildings) },
            |buildings| async {
                let g = generate(
                    &state.generator,
                    area,
                    Buildings::Loaded(buildings),
                    Some(plan.choice),
                    MeshOptions::new(&state.generator, key.encoding).with_tags(key.tags),
                )
                .await?;
                Ok::<_, AppError>((g.glb, g.stats))
            },
        )
        .await?;
    let mut response = cached_response(request_headers, cached, level, cache_control).await?;
    add_roofs_header(&mut response, &plan.chosen);
    Ok(response)
}

/// A scene with roofs as asked, and how they were chosen. Box scenes with roofs from tags and
/// heights as the server counts them come from the scene cache when they were made before
/// (classified and inferred ones depend on predictions and priors, and are made each time).
pub async fn generate_with_roofs(
    state: &AppState,
    area: SceneArea,
    roofs: RoofsParam,
    mesh: MeshOptions,
) -> Result<(Generated, ChosenRoofs), AppError> {
    if let Some(plan) = plan(state, area, roofs).await? {
        let generated = generate(
            &state.generator,
            area,
            Buildings::Loaded(plan.buildings),
            Some(plan.choice),
            mesh,
        )
        .await?;
        return Ok((generated, plan.chosen));
    }
    let bbox = match area {
        SceneArea::Bbox(b) if mesh.heights == state.generator.height_base => b,
        _ => {
            return Ok((
                generate(&state.generator, area, Buildings::FromSource, None, mesh).await?,
                ChosenRoofs::TagsOnly,
            ));
        }
    };
    let key = TileKey::bbox(bbox)
        .with_encoding(mesh.encoding)
        .with_tags(mesh.tags);
    let (scene, hit) = state
        .tiles
        .scenes
        .get_or_generate(key, || async {
            let g = generate(&state.generator, area, Buildings::FromSource, None, mesh).await?;
            Ok::<_, AppError>((g.glb, g.stats))
        })
        .await?;
    let generated = Generated {
        glb: scene.glb,
        stats: (*scene.stats).clone(),
        from_cache: hit,
    };
    Ok((generated, ChosenRoofs::TagsOnly))
}

/// A generated scene's response, with `X-Citymesh-Roofs` when roofs were chosen.
pub fn scene_response(
    request_headers: &HeaderMap,
    (generated, chosen): (Generated, ChosenRoofs),
    cache_control: &'static str,
) -> Response {
    let mut response = generated_response(request_headers, generated, cache_control);
    add_roofs_header(&mut response, &chosen);
    response
}

fn add_roofs_header(response: &mut Response, chosen: &ChosenRoofs) {
    if let Some(v) = chosen.header().and_then(|h| HeaderValue::from_str(&h).ok()) {
        response.headers_mut().insert(ROOFS_HEADER, v);
    }
}

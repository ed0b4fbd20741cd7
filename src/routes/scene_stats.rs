//! `GET /scene/stats?bbox=`: what went into the scene of an area, as JSON.

use super::params::{BboxQuery, heights_for, parse_bbox};
use super::roofs::{ChosenRoofs, generate_with_roofs};
use crate::error::{AppError, ErrorBody};
use crate::pipeline::{Generated, InferredFigures, MeshOptions, RoofFigures, RoofsParam};
use crate::state::AppState;
use axum::Json;
use axum::extract::rejection::QueryRejection;
use axum::extract::{Query, State};
use citymesh_core::building::BuildingStats;
use citymesh_core::mesh::Encoding;
use citymesh_core::scene::SceneArea;
use serde::Serialize;
use std::collections::BTreeMap;
use utoipa::ToSchema;

/// The statistics of the paper's Tables 2 and 3 for one scene, and what was skipped.
#[derive(Debug, Serialize, ToSchema)]
pub struct SceneStats {
    /// The paper's figures: time, vertices, triangles, bytes, and where roof shapes came from.
    #[serde(flatten)]
    pub figures: PaperFigures,
    /// `osm`, `classified` or `inferred`.
    pub roofs: RoofsParam,
    /// With `roofs=classified`: untagged buildings classified, below the threshold, and still
    /// without a prediction.
    pub classified_roofs: Option<RoofFigures>,
    /// With `roofs=inferred`: untagged buildings given a shape by the roof prior, below its
    /// threshold, and not inferred (the prior abstains), with each prior's cross-validated
    /// report.
    pub inferred_roofs: Option<InferredFigures>,
    /// With `roofs=classified`: the same scene without the classifier (the paper's Table 2
    /// columns side by side).
    pub without_classifier: Option<PaperFigures>,
    /// With `roofs=classified`: whom to credit for the imagery the roofs were classified from.
    pub imagery_attribution: Option<String>,
    pub buildings: BuildingFigures,
    pub ground: GroundFigures,
}

/// The figures of the paper's Tables 2 and 3 for one scene.
#[derive(Debug, Serialize, ToSchema)]
pub struct PaperFigures {
    /// Generation time of the mesh and its GLB, milliseconds.
    pub generation_ms: f64,
    /// Vertices and triangles in the GLB (ground and buildings).
    pub vertices: usize,
    pub triangles: usize,
    /// Size of the GLB `/scene.glb` returns for the same box.
    pub glb_bytes: usize,
    /// Share of flat roofs among generated buildings, percent.
    pub flat_roof_percent: f64,
    /// Share of roof shapes taken from `roof:shape` tags, percent (the rest are from the
    /// classifier, defaults, or unsupported shapes rendered flat).
    pub roof_shape_from_tag_percent: f64,
    /// Share of roof shapes from the roof classifier, percent (0 with `roofs=osm`).
    pub roof_shape_from_classifier_percent: f64,
    /// Share of roof shapes inferred by the roof prior, percent (0 unless `roofs=inferred`).
    pub roof_shape_inferred_percent: f64,
    /// Share of roofs given the default (flat) shape, percent.
    pub roof_shape_default_percent: f64,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct BuildingFigures {
    /// Buildings and building parts generated.
    pub generated: usize,
    /// Of those, `building:part`s.
    pub parts: usize,
    /// Buildings skipped, by reason (e.g. `self_intersecting`).
    pub skipped: BTreeMap<String, usize>,
    /// The skipped buildings (`way/123`, `relation/45`) with their reason: those the generator
    /// could not build, and those the data near the box has but that could not be read into a
    /// building at all (e.g. `missing_nodes`).
    pub skipped_ids: Vec<SkippedBuilding>,
    /// Buildings generated with less than the data describes, e.g. `missing_inner_ring` (a
    /// courtyard missing from the data: the outline is drawn without it).
    pub repaired_ids: Vec<RepairedBuilding>,
    /// Buildings whose `roof:shape` names no shape citymesh draws (drawn flat), with the value.
    pub roof_shape_unsupported_ids: Vec<UnsupportedShape>,
    /// Buildings whose drawn floor covers less of their outline than it should, by more than
    /// 1 m², with the square metres missing (floor, walls and roof over them).
    pub area_lost_ids: Vec<AreaLost>,
    /// Generated roofs per shape.
    pub roof_shapes: BTreeMap<String, usize>,
    /// Roof shapes from a `roof:shape` tag, from the classifier, inferred by the roof prior, by
    /// default (no tag: flat), and tags naming a shape citymesh does not draw (rendered flat).
    pub roof_shape_from_tag: usize,
    pub roof_shape_from_classifier: usize,
    pub roof_shape_inferred: usize,
    pub roof_shape_default: usize,
    pub roof_shape_unsupported: usize,
    /// Total heights from `height`, from `building:levels`, and from the building type's default.
    pub height_from_tag: usize,
    pub height_from_levels: usize,
    pub height_default: usize,
    /// Tag values present but unusable ("tall", negative, NaN): the fallback was used.
    pub invalid_tag_values: usize,
    /// Outlines entirely covered by their `building:part`s (only the parts are drawn).
    pub outlines_covered_by_parts: usize,
    /// Walls between touching buildings, removed as hidden.
    pub shared_walls: usize,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct UnsupportedShape {
    pub id: String,
    /// The `roof:shape` value.
    pub shape: String,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct AreaLost {
    pub id: String,
    /// Square metres of the outline not drawn.
    pub m2: f64,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct SkippedBuilding {
    pub id: String,
    pub reason: String,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct RepairedBuilding {
    pub id: String,
    /// What was left out.
    pub what: String,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct GroundFigures {
    /// Ground cells (SRTM samples) in the box, and those left empty by DEM voids.
    pub cells: usize,
    pub void_cells: usize,
    /// 1x1 degree areas without a DEM file (flat 0 m ground there).
    pub missing_dem: Vec<String>,
}

/// Statistics of the scene of a bounding box.
///
/// Generates the same scene as `/scene.glb` and reports generation time, vertex and triangle
/// counts, the share of flat roofs and of roof shapes from tags, the classifier and defaults (the
/// paper's Tables 2 and 3), buildings generated and skipped with reasons, and where the ground
/// came from. With `roofs=classified`, the same figures without the classifier come alongside.
#[utoipa::path(get, path = "/scene/stats", tag = "meshes", params(BboxQuery),
    responses(
        (status = 200, description = "The figures", body = SceneStats),
        (status = 400, description = "The bbox is missing, malformed, inverted, out of range or too large", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer; nothing was stored", body = ErrorBody),
        (status = 503, description = "Overpass is rate limiting, or every generation slot is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn scene_stats(
    State(state): State<AppState>,
    query: Result<Query<BboxQuery>, QueryRejection>,
) -> Result<Json<SceneStats>, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let bbox = parse_bbox(query.bbox.as_deref(), &state.generator.limits)?;
    let area = SceneArea::Bbox(bbox);
    let roofs = query.roofs.unwrap_or_default();
    let mesh = MeshOptions {
        encoding: Encoding::Plain,
        heights: heights_for(&state, query.height_base),
        tags: Default::default(),
    };
    let (generated, chosen) = generate_with_roofs(&state, area, roofs, mesh).await?;
    let mut stats = SceneStats::of(&generated, &chosen);
    if roofs == RoofsParam::Classified {
        let (plain, _) = generate_with_roofs(&state, area, RoofsParam::Osm, mesh).await?;
        stats.without_classifier = Some(PaperFigures::of(&plain));
        stats.imagery_attribution = Some(state.generator.roofs.imagery_attribution.clone());
    }
    Ok(Json(stats))
}

/// Roofs from tags, from the classifier, inferred and by default (the core counts chosen roofs
/// as tagged: they reach it as tags).
fn roof_sources(generated: &Generated) -> [f64; 4] {
    let b = &generated.stats.buildings;
    let chosen = generated.stats.chosen_roofs;
    let inferred = generated.stats.inferred_roofs;
    let share = |n: usize| {
        if b.roofs() == 0 {
            0.0
        } else {
            100.0 * n as f64 / b.roofs() as f64
        }
    };
    [
        share(b.shape_from_tag.saturating_sub(chosen + inferred)),
        share(chosen),
        share(inferred),
        share(b.shape_default),
    ]
}

impl PaperFigures {
    pub fn of(generated: &Generated) -> Self {
        let s = &generated.stats;
        let [tag, classifier, inferred, default] = roof_sources(generated);
        Self {
            generation_ms: s.generation_ms,
            vertices: s.vertices,
            triangles: s.triangles,
            glb_bytes: generated.glb.len(),
            flat_roof_percent: s.buildings.flat_roof_percent(),
            roof_shape_from_tag_percent: tag,
            roof_shape_from_classifier_percent: classifier,
            roof_shape_inferred_percent: inferred,
            roof_shape_default_percent: default,
        }
    }
}

impl BuildingFigures {
    /// The figures of a scene's buildings, `chosen_roofs` of whose roofs the classifier chose
    /// and `inferred_roofs` the roof prior (the core counts both as tagged). `citymesh scene
    /// --stats` writes the same.
    pub fn of(b: &BuildingStats, chosen_roofs: usize, inferred_roofs: usize) -> Self {
        BuildingFigures {
            generated: b.generated,
            parts: b.parts,
            skipped: b
                .skipped
                .iter()
                .map(|(k, v)| ((*k).to_owned(), *v))
                .collect(),
            skipped_ids: b
                .skipped_ids
                .iter()
                .map(|(id, reason)| SkippedBuilding {
                    id: id.clone(),
                    reason: (*reason).to_owned(),
                })
                .collect(),
            repaired_ids: b
                .repaired_ids
                .iter()
                .map(|(id, what)| RepairedBuilding {
                    id: id.clone(),
                    what: (*what).to_owned(),
                })
                .collect(),
            roof_shape_unsupported_ids: b
                .unsupported_shape_ids
                .iter()
                .map(|(id, shape)| UnsupportedShape {
                    id: id.clone(),
                    shape: shape.clone(),
                })
                .collect(),
            area_lost_ids: b
                .area_lost_ids
                .iter()
                .map(|(id, m2)| AreaLost {
                    id: id.clone(),
                    m2: *m2,
                })
                .collect(),
            roof_shapes: b
                .roof_shapes
                .iter()
                .map(|(k, v)| ((*k).to_owned(), *v))
                .collect(),
            roof_shape_from_tag: b
                .shape_from_tag
                .saturating_sub(chosen_roofs + inferred_roofs),
            roof_shape_from_classifier: chosen_roofs,
            roof_shape_inferred: inferred_roofs,
            roof_shape_default: b.shape_default,
            roof_shape_unsupported: b.shape_unsupported,
            height_from_tag: b.height_from_tag,
            height_from_levels: b.height_from_levels,
            height_default: b.height_default,
            invalid_tag_values: b.invalid_tags,
            outlines_covered_by_parts: b.outlines_covered_by_parts,
            shared_walls: b.shared_walls,
        }
    }
}

impl SceneStats {
    /// The figures of a generated scene, and of its chosen roofs.
    pub fn of(generated: &Generated, chosen: &ChosenRoofs) -> Self {
        let s = &generated.stats;
        let b = &s.buildings;
        let (roofs, classified, inferred) = match chosen {
            ChosenRoofs::TagsOnly => (RoofsParam::Osm, None, None),
            ChosenRoofs::Classified(f) => (RoofsParam::Classified, Some(*f), None),
            ChosenRoofs::Inferred(f) => (RoofsParam::Inferred, None, Some(f.clone())),
        };
        SceneStats {
            figures: PaperFigures::of(generated),
            roofs,
            classified_roofs: classified,
            inferred_roofs: inferred,
            without_classifier: None,
            imagery_attribution: None,
            buildings: BuildingFigures::of(b, s.chosen_roofs, s.inferred_roofs),
            ground: GroundFigures {
                cells: s.ground.cells,
                void_cells: s.ground.void_cells,
                missing_dem: s.missing_dem.clone(),
            },
        }
    }
}

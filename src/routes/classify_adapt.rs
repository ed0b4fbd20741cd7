//! Adapting the roof classifier to the served imagery over HTTP (docs/extensions.md section 3):
//! `POST /classify/adapt` takes the buildings of a box whose `roof:shape` OpenStreetMap tags as
//! examples, crops and embeds them and fits a new head in the background; `GET
//! /classify/adapt/{id}` reports its progress and, once fitted, its cross-validated report. The
//! head is then in use for this imagery: `POST /classify` queues new predictions made with it.

use super::classify::{BboxValue, classification_unavailable, json_rejection};
use super::params::parse_bbox;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::within_timeout;
use crate::roofs::jobs::adapt::{
    AdaptExample, AdaptFailure, AdaptationStatus, ClassCounts, class_counts, tagged_examples,
};
use crate::state::AppState;
use axum::Json;
use axum::extract::rejection::{JsonRejection, PathRejection};
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use citymesh_core::roof_image::RoofClass;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Where to learn from.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AdaptRequest {
    /// The area as `"minLon,minLat,maxLon,maxLat"` or `[minLon, minLat, maxLon, maxLat]`: its
    /// buildings whose footprint's centre lies in it and whose `roof:shape` is flat, gabled,
    /// hipped or pyramidal are the examples.
    pub bbox: BboxValue,
}

/// An adaptation as started.
#[derive(Debug, Serialize, ToSchema)]
pub struct AdaptationCreated {
    /// 128 random bits, hex.
    pub id: String,
    /// Where to follow it.
    pub progress: String,
    /// Tagged buildings found, by class (at most 300 per class are used).
    pub examples: ClassCounts,
    pub imagery_id: String,
    pub model_id: String,
}

fn too_few(detail: String) -> AppError {
    AppError::Document {
        status: StatusCode::UNPROCESSABLE_ENTITY,
        code: "too_few_examples",
        detail,
        feature: None,
        field: Some("bbox".into()),
    }
}

/// Adapt the roof classifier to the served imagery from the area's tagged roofs.
///
/// Takes the buildings of the box whose `roof:shape` tag names one of the three classes (flat;
/// gabled; hipped or pyramidal), crops each from the imagery as any building is cropped, and fits
/// a new head on the model's embedding of them (a logistic regression, cross-validated in 5
/// folds; docs/extensions.md section 3). Answers at once; follow it at `GET
/// /classify/adapt/{id}`. When fitted, the head is in use for this imagery: predictions queued
/// afterwards (`POST /classify`) are made with it and record its id in their `model_id`. Needs
/// at least 20 examples per class; one adaptation at a time per imagery.
#[utoipa::path(post, path = "/classify/adapt", tag = "classification", request_body = AdaptRequest,
    responses(
        (status = 202, description = "The adaptation is running", body = AdaptationCreated),
        (status = 400, description = "The body or the bbox is invalid", body = ErrorBody),
        (status = 409, description = "An adaptation is already running for this imagery", body = ErrorBody),
        (status = 413, description = "The body is too large", body = ErrorBody),
        (status = 422, description = "The area has fewer than 20 tagged buildings of a class", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer", body = ErrorBody),
        (status = 503, description = "Classification is not available on this server (no classifier or no imagery), or Overpass is busy", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn post_adapt(
    State(state): State<AppState>,
    body: Result<Json<AdaptRequest>, JsonRejection>,
) -> Result<Response, AppError> {
    let Json(request) = body.map_err(|e| {
        json_rejection(
            e,
            "send JSON like {\"bbox\": \"8.396,49.052,8.403,49.058\"}",
        )
    })?;
    let roofs = state.generator.roofs.clone();
    if let Some(why) = roofs.why_not_running() {
        return Err(classification_unavailable(why));
    }
    let Some(base) = roofs.base.as_ref() else {
        return Err(classification_unavailable(
            "the roof classifier is not loaded: start the server with --roof-classifier",
        ));
    };
    let model_id = crate::roofs::classifier::RoofClassifier::model_id(base.as_ref()).to_owned();
    let bbox = parse_bbox(Some(&request.bbox.text()), &state.generator.limits)?;
    // The check that none runs and the start are one step: of concurrent requests, one starts
    // and the others get 409 before gathering anything.
    let id = crate::roofs::jobs::random_token()?;
    let lease = &roofs.adapt_policy.lease;
    if let Some(running) = roofs
        .adaptations
        .start(
            &id,
            &bbox.to_string(),
            &roofs.imagery_id,
            &model_id,
            [0; 3],
            lease,
        )
        .await?
    {
        return Err(AppError::Document {
            status: StatusCode::CONFLICT,
            code: "adaptation_running",
            detail: format!(
                "adaptation {running} is running for this imagery; follow it at \
                 /classify/adapt/{running} and ask again when it has ended"
            ),
            feature: None,
            field: None,
        });
    }
    let examples = match gather_examples(&state, &bbox).await {
        Ok(examples) => examples,
        Err(e) => {
            let why = AdaptFailure::Failed(format!("gathering the examples failed: {e}"));
            if let Err(e) = roofs.adaptations.record(&id, &Err(why), false).await {
                tracing::warn!(adaptation = %id, error = %e, "cannot record the adaptation's end");
            }
            return Err(e);
        }
    };
    let counts = class_counts(&examples);
    roofs.adaptations.set_examples(&id, counts).await?;
    let min = crate::roofs::classifier::head::MIN_PER_CLASS;
    if counts.iter().any(|&n| n < min) {
        let found: Vec<String> = RoofClass::ALL
            .iter()
            .map(|c| format!("{} {}", counts[c.index()], c.name()))
            .collect();
        let detail = format!(
            "the area has {} tagged buildings; at least {min} of each class are needed: choose a \
             larger area or one with more roof:shape tags (the shipped head stays in use)",
            found.join(", ")
        );
        let outcome = Err(AdaptFailure::TooFew(detail.clone()));
        roofs.adaptations.record(&id, &outcome, false).await?;
        return Err(too_few(detail));
    }
    roofs.spawn_adaptation(id.clone(), examples);
    let created = AdaptationCreated {
        progress: format!("/classify/adapt/{id}"),
        id,
        examples: ClassCounts::of(counts),
        imagery_id: roofs.imagery_id.clone(),
        model_id,
    };
    Ok((StatusCode::ACCEPTED, Json(created)).into_response())
}

/// The tagged buildings of the box, gathered under the request timeout as a scene's are.
async fn gather_examples(
    state: &AppState,
    bbox: &citymesh_core::geo::GeoBbox,
) -> Result<Vec<AdaptExample>, AppError> {
    let buildings = within_timeout(&state.generator, async {
        Ok::<_, AppError>(state.generator.source.buildings(bbox).await?)
    })
    .await?;
    Ok(tagged_examples(buildings.set.records(), Some(bbox)))
}

/// An adaptation as ended by `DELETE`.
#[derive(Debug, Serialize, ToSchema)]
pub struct AdaptationEnded {
    pub id: String,
    /// `cancelled` (it was running: its work stops) or `withdrawn` (it was done: its head is no
    /// longer in use).
    pub state: String,
    /// The model predictions are made with now.
    pub model_id: String,
}

fn adaptation_id(path: Result<Path<String>, PathRejection>) -> Result<String, AppError> {
    let Path(id) = path.map_err(|e| AppError::bad_request("invalid_id", e.body_text()))?;
    if id.len() != 32 || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(AppError::bad_request(
            "invalid_id",
            format!("'{id}' is not an adaptation id (32 hex digits)"),
        ));
    }
    Ok(id.to_ascii_lowercase())
}

/// Cancel an adaptation, or withdraw its head.
///
/// A running adaptation stops (within one crop or one fold's fit, on whichever replica runs it)
/// and is `cancelled`; a done one is `withdrawn`: its head is no longer used, and the newest
/// other head adapted to this imagery, or the shipped one, is used again. Either way the
/// adaptation is deleted: `GET` and `DELETE` on it answer 404 afterwards.
#[utoipa::path(delete, path = "/classify/adapt/{id}", tag = "classification",
    params(("id" = String, Path, description = "The id `POST /classify/adapt` answered (32 hex digits)")),
    responses(
        (status = 200, description = "Cancelled or withdrawn", body = AdaptationEnded),
        (status = 400, description = "The id is not 32 hex digits", body = ErrorBody),
        (status = 404, description = "No such adaptation (or it was deleted)", body = ErrorBody),
        (status = 409, description = "The adaptation has already ended without a head in use", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn delete_adapt(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<AdaptationEnded>, AppError> {
    let id = adaptation_id(path)?;
    let roofs = &state.generator.roofs;
    let before =
        roofs.adaptations.cancel(&id).await?.ok_or_else(|| {
            AppError::not_found("no_such_adaptation", format!("no adaptation {id}"))
        })?;
    let ended = match before.as_str() {
        "running" => {
            roofs.stop_adaptation(&id);
            "cancelled"
        }
        "done" => {
            roofs.use_newest_or_shipped().await?;
            "withdrawn"
        }
        other if is_deleted(other) => return Err(deleted(&id, other)),
        other => {
            return Err(AppError::Document {
                status: StatusCode::CONFLICT,
                code: "adaptation_ended",
                detail: format!(
                    "adaptation {id} has already ended ({other}) and has no head in use: \
                     nothing to cancel"
                ),
                feature: None,
                field: None,
            });
        }
    };
    Ok(Json(AdaptationEnded {
        id,
        state: ended.to_owned(),
        model_id: roofs.active().model_id.clone(),
    }))
}

/// An adaptation's progress and report.
#[utoipa::path(get, path = "/classify/adapt/{id}", tag = "classification",
    params(("id" = String, Path, description = "The id `POST /classify/adapt` answered (32 hex digits)")),
    responses(
        (status = 200, description = "Its state, progress and, once fitted, its report", body = AdaptationStatus),
        (status = 400, description = "The id is not 32 hex digits", body = ErrorBody),
        (status = 404, description = "No such adaptation", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn get_adapt(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<AdaptationStatus>, AppError> {
    let id = adaptation_id(path)?;
    match state.generator.roofs.adaptations.get(&id).await? {
        Some(a) if is_deleted(&a.state) => Err(deleted(&id, &a.state)),
        Some(a) => Ok(Json(a)),
        None => Err(AppError::not_found(
            "no_such_adaptation",
            format!("no adaptation {id}"),
        )),
    }
}

/// Whether a `DELETE` ended the adaptation (`cancelled` or `withdrawn`): the API answers 404
/// for it from then on (its row stays, so a replica still running it sees its lease lost).
fn is_deleted(state: &str) -> bool {
    matches!(state, "cancelled" | "withdrawn")
}

fn deleted(id: &str, state: &str) -> AppError {
    AppError::not_found(
        "no_such_adaptation",
        format!("no adaptation {id}: it was deleted ({state} by DELETE)"),
    )
}

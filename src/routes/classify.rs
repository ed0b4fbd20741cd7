//! Roof classification jobs over HTTP (docs/extensions.md section 1): `POST /classify` queues a job
//! per untagged building of a box, `GET /classify/{id}` reports a batch's progress,
//! `DELETE /classify/{id}` cancels its queued jobs, and `GET /classify/predictions?bbox=` gives
//! the predictions as GeoJSON. Workers run the jobs (`--classify-workers`); tiles use the results
//! with `roofs=classified`.

use super::params::parse_bbox;
use crate::error::{AppError, ErrorBody};
use crate::pipeline::within_timeout;
use crate::roofs::jobs::batch_budget::{Refusal, batch_bytes};
use crate::roofs::jobs::{BatchCounts, BatchProgress, Selection, jobs_in_box};
use crate::server::ClientAddr;
use crate::state::AppState;
use axum::Extension;
use axum::Json;
use axum::extract::rejection::{JsonRejection, PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use citymesh_core::roof_image::RoofClass;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::collections::BTreeMap;
use utoipa::{IntoParams, ToSchema};

/// Most jobs one batch may queue: a larger area is asked for in parts.
pub const MAX_JOBS_PER_BATCH: usize = 20_000;
/// Most features one predictions answer holds.
pub const MAX_PREDICTIONS: u32 = 10_000;
/// Half the side (degrees, about 55 m) of the box searched around features that span no area,
/// such as points naming buildings.
pub const POINT_MARGIN_DEG: f64 = 0.0005;

/// A box as text, `minLon,minLat,maxLon,maxLat`, or as the GeoJSON array
/// `[minLon, minLat, maxLon, maxLat]`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum BboxValue {
    #[schema(example = "8.400,49.010,8.409,49.017")]
    Text(String),
    #[schema(example = json!([8.400, 49.010, 8.409, 49.017]))]
    Array([f64; 4]),
}

impl BboxValue {
    /// The box as the text `parse_bbox` reads (an array's numbers written as they are).
    pub fn text(&self) -> String {
        match self {
            Self::Text(t) => t.clone(),
            Self::Array([w, s, e, n]) => format!("{w},{s},{e},{n}"),
        }
    }
}

/// What to classify.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ClassifyRequest {
    /// The area as `"minLon,minLat,maxLon,maxLat"` or `[minLon, minLat, maxLon, maxLat]`:
    /// buildings whose footprint's centre lies in it.
    pub bbox: BboxValue,
    /// Only these buildings of the area (`way/123`, `relation/45`); all when absent.
    #[serde(default)]
    pub osm_ids: Option<Vec<String>>,
    /// Classify buildings that have a `roof:shape` tag too (to compare with the tags); by
    /// default only untagged ones, the paper's rule.
    #[serde(default)]
    pub include_tagged: bool,
}

/// What to classify: a box, or the buildings a GeoJSON FeatureCollection names.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum ClassifyBody {
    Area(ClassifyRequest),
    Features(FeatureSelection),
}

/// A GeoJSON FeatureCollection whose features name buildings by `properties.osm_id` (`way/123`,
/// `relation/45`; `@id` and `id` are read too), such as `GET /classify/predictions` answers or
/// an export from another tool. The area searched is the extent of the features' geometry,
/// widened to about 110 m where it is thinner (features given as points).
#[derive(Debug, Deserialize, ToSchema)]
pub struct FeatureSelection {
    /// `FeatureCollection`.
    #[serde(rename = "type")]
    pub kind: String,
    /// At most 20,000 features, each with a geometry and an OSM id.
    #[schema(value_type = Vec<Object>)]
    pub features: Vec<serde_json::Value>,
    #[serde(default)]
    pub include_tagged: bool,
}

impl FeatureSelection {
    /// The box around the features' coordinates and their OSM ids.
    fn area_and_ids(&self) -> Result<(String, Vec<String>), AppError> {
        let bad = |detail: String| AppError::bad_request("invalid_geojson", detail);
        if self.kind != "FeatureCollection" {
            return Err(bad(format!(
                "type is '{}', not FeatureCollection",
                self.kind
            )));
        }
        if self.features.is_empty() || self.features.len() > MAX_JOBS_PER_BATCH {
            return Err(bad(format!(
                "{} features: send 1 to {MAX_JOBS_PER_BATCH}",
                self.features.len()
            )));
        }
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        let mut ids = Vec::with_capacity(self.features.len());
        for (i, f) in self.features.iter().enumerate() {
            let p = &f["properties"];
            let id = ["osm_id", "@id", "id"]
                .iter()
                .find_map(|k| p[*k].as_str())
                .ok_or_else(|| bad(format!("feature {i} has no properties.osm_id")))?;
            ids.push(id.to_owned());
            let mut points = 0;
            visit_positions(&f["geometry"]["coordinates"], 0, &mut |lon, lat| {
                lo = [lo[0].min(lon), lo[1].min(lat)];
                hi = [hi[0].max(lon), hi[1].max(lat)];
                points += 1;
            });
            if points == 0 {
                return Err(bad(format!("feature {i} ({id}) has no coordinates")));
            }
        }
        // Features given as points (or a line along a meridian or a parallel) span no area: the
        // box is widened to reach the buildings they name.
        for k in 0..2 {
            if hi[k] - lo[k] < 2.0 * POINT_MARGIN_DEG {
                let mid = (lo[k] + hi[k]) / 2.0;
                lo[k] = mid - POINT_MARGIN_DEG;
                hi[k] = mid + POINT_MARGIN_DEG;
            }
        }
        Ok((format!("{},{},{},{}", lo[0], lo[1], hi[0], hi[1]), ids))
    }
}

/// Calls `f` with every `[lon, lat, ...]` position of GeoJSON coordinates (nested at most 4
/// deep, as MultiPolygons are).
fn visit_positions(v: &serde_json::Value, depth: u8, f: &mut dyn FnMut(f64, f64)) {
    let Some(items) = v.as_array() else {
        return;
    };
    match (
        items.first().and_then(serde_json::Value::as_f64),
        items.get(1).and_then(serde_json::Value::as_f64),
    ) {
        (Some(lon), Some(lat)) if lon.is_finite() && lat.is_finite() => f(lon, lat),
        (Some(_), Some(_)) => {}
        _ if depth < 4 => {
            for item in items {
                visit_positions(item, depth + 1, f);
            }
        }
        _ => {}
    }
}

/// A batch as queued.
#[derive(Debug, Serialize, ToSchema)]
pub struct BatchCreated {
    /// The batch's token: 32 hex digits, unguessable; whoever holds it can follow or delete the
    /// batch.
    pub id: String,
    /// Where to follow it.
    pub progress: String,
    pub counts: BatchCounts,
    pub imagery_id: String,
    pub imagery_attribution: String,
    pub model_id: String,
}

/// A batch's progress, and whose imagery it uses.
#[derive(Debug, Serialize, ToSchema)]
pub struct BatchStatus {
    #[serde(flatten)]
    pub progress: BatchProgress,
    pub imagery_attribution: String,
    /// Share of the batch's jobs that have ended (done, failed or cancelled), percent.
    pub percent_ended: f64,
}

#[derive(Debug, Serialize, ToSchema)]
pub struct BatchCancelled {
    pub id: String,
    /// Queued jobs cancelled now (running ones finish).
    pub cancelled: u64,
}

#[derive(Debug, Deserialize, IntoParams)]
#[into_params(parameter_in = Query)]
pub struct PredictionsQuery {
    /// The area as `minLon,minLat,maxLon,maxLat`: predictions whose footprint meets it.
    #[param(required = true, example = "8.400,49.010,8.409,49.017")]
    pub bbox: Option<String>,
}

fn bad_json(e: JsonRejection) -> AppError {
    json_rejection(
        e,
        "send JSON like {\"bbox\": \"8.400,49.010,8.409,49.017\"} (or [8.400, 49.010, 8.409, \
         49.017]), or a GeoJSON FeatureCollection whose features have properties.osm_id",
    )
}

/// The answer to a JSON body that could not be read: 413 when it is larger than the route
/// takes, else 400, saying what to send.
pub(super) fn json_rejection(e: JsonRejection, what_to_send: &str) -> AppError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        return AppError::Document {
            status: StatusCode::PAYLOAD_TOO_LARGE,
            code: "body_too_large",
            detail: format!(
                "the body is larger than this route takes ({}); {what_to_send}",
                e.body_text()
            ),
            feature: None,
            field: None,
        };
    }
    AppError::bad_request("invalid_body", format!("{}; {what_to_send}", e.body_text()))
}

fn batch_id(path: Result<Path<String>, PathRejection>) -> Result<String, AppError> {
    let Path(text) = path.map_err(|e| AppError::bad_request("invalid_id", e.body_text()))?;
    if crate::roofs::jobs::is_token(&text) {
        Ok(text)
    } else {
        Err(AppError::bad_request(
            "invalid_id",
            "that is not a batch id: send the 32 hex digits POST /classify answered as `id`",
        ))
    }
}

/// A batch that exists and was neither deleted nor expired (either is gone for clients; its
/// finished jobs keep their predictions).
async fn live_batch(state: &AppState, id: &str) -> Result<BatchProgress, AppError> {
    let kept = state.generator.roofs.batches.limits.ttl.as_secs_f64();
    match state.generator.roofs.queue.progress(id).await? {
        Some(p) if !p.cancelled => Ok(p),
        Some(_) if state.generator.roofs.batches.is_expired(id).await? => Err(AppError::not_found(
            "no_such_batch",
            format!(
                "batch {id} expired: finished batches are kept {kept} s after their last job ended (its predictions stay: GET /classify/predictions)"
            ),
        )),
        Some(_) => Err(AppError::not_found(
            "no_such_batch",
            format!("batch {id} was deleted"),
        )),
        None => Err(AppError::not_found(
            "no_such_batch",
            format!(
                "no batch {id} (finished batches are kept {kept} s after their last job ended)"
            ),
        )),
    }
}

/// The answer to a batch the budget refused: 429 past the client's share, 503 past the whole
/// budget, both with Retry-After.
fn refused(refusal: Refusal, ttl: std::time::Duration) -> AppError {
    let retry_after_secs = ttl.as_secs().clamp(1, 60);
    match refusal {
        Refusal::OverShare { used, share } => AppError::TooMany {
            code: "too_many_batches",
            detail: format!(
                "your classification batches keep {used} bytes in the store and this one would \
                 pass your share ({share} bytes, --classify-client-share-percent): delete \
                 finished batches (DELETE /classify/{{id}}) or wait for them to expire \
                 ({} s after they finish)",
                ttl.as_secs_f64()
            ),
            retry_after_secs,
        },
        Refusal::OverBudget { used, max } => AppError::Unavailable {
            code: "batch_store_full",
            detail: format!(
                "classification batches keep {used} bytes in the store and this one would pass \
                 its bound ({max} bytes, --classify-store-mb): try again when batches have \
                 expired"
            ),
            retry_after_secs,
        },
    }
}

/// Queue roof classification for the buildings of an area.
///
/// Queues one job per building without `roof:shape` (and without building parts) whose
/// footprint's centre lies in the box (or, for a GeoJSON FeatureCollection, each building its
/// features name by `properties.osm_id`), unless it is already queued or classified for the same
/// footprint, imagery and model. Answers at once with the batch id and counts; follow it at
/// `GET /classify/{id}`. Needs the server started with `--roof-classifier` and `--imagery-url`.
#[utoipa::path(post, path = "/classify", tag = "classification", request_body = ClassifyBody,
    responses(
        (status = 202, description = "The batch is queued", body = BatchCreated),
        (status = 400, description = "The body or the bbox is invalid, or the area has too many buildings", body = ErrorBody),
        (status = 413, description = "The body is too large", body = ErrorBody),
        (status = 429, description = "Your batches hold your share of the batch store; see Retry-After", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
        (status = 502, description = "Overpass failed or sent an incomplete answer", body = ErrorBody),
        (status = 503, description = "Classification is not available on this server (no classifier or no imagery), the batch store is full, or Overpass is busy; see Retry-After", body = ErrorBody),
        (status = 504, description = "Overpass did not answer in time", body = ErrorBody),
    ))]
pub async fn post_classify(
    State(state): State<AppState>,
    client: Option<Extension<ClientAddr>>,
    body: Result<Json<ClassifyBody>, JsonRejection>,
) -> Result<Response, AppError> {
    let request = match body.map_err(bad_json)? {
        Json(ClassifyBody::Area(request)) => request,
        Json(ClassifyBody::Features(selection)) => {
            let (bbox, ids) = selection.area_and_ids()?;
            ClassifyRequest {
                bbox: BboxValue::Text(bbox),
                osm_ids: Some(ids),
                include_tagged: selection.include_tagged,
            }
        }
    };
    let roofs = state.generator.roofs.clone();
    if let Some(why) = roofs.why_not_running() {
        return Err(classification_unavailable(why));
    }
    let bbox = parse_bbox(Some(&request.bbox.text()), &state.generator.limits)?;
    // Gathering the buildings may ask upstream: under the request timeout, as a scene is.
    let buildings = within_timeout(&state.generator, async {
        Ok::<_, AppError>(state.generator.source.buildings(&bbox).await?)
    })
    .await?;
    let selection = if request.include_tagged {
        Selection::All
    } else {
        Selection::Untagged
    };
    let wanted: Option<std::collections::HashSet<&str>> = request
        .osm_ids
        .as_ref()
        .map(|ids| ids.iter().map(String::as_str).collect());
    // The buildings the box holds (the core's rule), skipped ones counted too.
    let (jobs, skipped) = jobs_in_box(
        buildings.set.records(),
        Some(&bbox),
        selection,
        wanted.as_ref(),
    );
    if jobs.len() > MAX_JOBS_PER_BATCH {
        return Err(AppError::bad_request(
            "too_many_buildings",
            format!(
                "the area has {} buildings to classify, more than {MAX_JOBS_PER_BATCH} per batch: \
                 split it into smaller boxes",
                jobs.len()
            ),
        ));
    }
    let model_id = roofs.active().model_id.clone();
    // What the batch keeps in the store, against the budget and the client's share of it.
    let client = client.map_or_else(|| "local".to_owned(), |Extension(c)| c.0.ip().to_string());
    let bytes = batch_bytes(jobs.len());
    let admission = match roofs.batches.admit(&client, bytes).await? {
        Ok(admission) => admission,
        Err(refusal) => return Err(refused(refusal, roofs.batches.limits.ttl)),
    };
    let (id, counts) = roofs
        .queue
        .enqueue(
            &bbox.to_string(),
            &roofs.imagery_id,
            &model_id,
            &jobs,
            skipped,
        )
        .await?;
    roofs.batches.record(admission, &id, &client, bytes).await?;
    roofs.refresh_state_metrics().await;
    let created = BatchCreated {
        progress: format!("/classify/{id}"),
        id,
        counts,
        imagery_id: roofs.imagery_id.clone(),
        imagery_attribution: roofs.imagery_attribution.clone(),
        model_id,
    };
    Ok((StatusCode::ACCEPTED, Json(created)).into_response())
}

/// A classification batch's progress.
#[utoipa::path(get, path = "/classify/{id}", tag = "classification",
    params(("id" = String, Path, description = "The batch id `POST /classify` answered (32 hex digits)", pattern = "^[0-9a-f]{32}$")),
    responses(
        (status = 200, description = "The batch's jobs by state", body = BatchStatus),
        (status = 400, description = "The id is not 32 hex digits", body = ErrorBody),
        (status = 404, description = "No such batch", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn get_batch(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<BatchStatus>, AppError> {
    let id = batch_id(path)?;
    let progress = live_batch(&state, &id).await?;
    let total: u64 = progress.jobs.values().sum();
    let ended = progress.jobs["done"] + progress.jobs["failed"] + progress.jobs["cancelled"];
    Ok(Json(BatchStatus {
        percent_ended: if total == 0 {
            100.0
        } else {
            100.0 * ended as f64 / total as f64
        },
        progress,
        imagery_attribution: state.generator.roofs.imagery_attribution.clone(),
    }))
}

/// Delete a batch: its queued jobs are cancelled (running ones finish; done ones keep their
/// predictions), and the batch is gone (`GET` answers 404).
#[utoipa::path(delete, path = "/classify/{id}", tag = "classification",
    params(("id" = String, Path, description = "The batch id `POST /classify` answered (32 hex digits)", pattern = "^[0-9a-f]{32}$")),
    responses(
        (status = 200, description = "Cancelled", body = BatchCancelled),
        (status = 400, description = "The id is not 32 hex digits", body = ErrorBody),
        (status = 404, description = "No such batch", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn delete_batch(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<BatchCancelled>, AppError> {
    let id = batch_id(path)?;
    live_batch(&state, &id).await?;
    let cancelled = state
        .generator
        .roofs
        .queue
        .cancel(&id)
        .await?
        .ok_or_else(|| AppError::not_found("no_such_batch", format!("no batch {id}")))?;
    state.generator.roofs.batches.release(&id).await?;
    state.generator.roofs.refresh_state_metrics().await;
    Ok(Json(BatchCancelled { id, cancelled }))
}

/// The roof predictions of an area, as GeoJSON.
///
/// A FeatureCollection: per classified building its footprint (Polygon), OSM id, the
/// probabilities of flat, gabled and hipped, the chosen shape, whether it clears the server's
/// threshold (and so shapes `roofs=classified` tiles), and the imagery and model it came from. At
/// most 10,000 features.
#[utoipa::path(get, path = "/classify/predictions", tag = "classification", params(PredictionsQuery),
    responses(
        (status = 200, description = "The predictions", content_type = "application/geo+json", body = Object),
        (status = 400, description = "The bbox is missing, malformed or too large", body = ErrorBody),
        (status = 500, description = "An internal failure; the server log has the cause", body = ErrorBody),
    ))]
pub async fn predictions(
    State(state): State<AppState>,
    query: Result<Query<PredictionsQuery>, QueryRejection>,
) -> Result<Response, AppError> {
    let Query(query) = query.map_err(|e| AppError::bad_request("invalid_query", e.body_text()))?;
    let bbox = parse_bbox(query.bbox.as_deref(), &state.generator.limits)?;
    let roofs = &state.generator.roofs;
    let threshold = roofs.active().threshold;
    let stored = roofs.queue.predictions(&bbox, MAX_PREDICTIONS).await?;
    let features: Vec<serde_json::Value> = stored
        .iter()
        .map(|s| {
            let p = &s.prediction;
            let mut ring = s.footprint.clone();
            if let Some(&first) = ring.first() {
                ring.push(first);
            }
            let probabilities: BTreeMap<&str, f32> = RoofClass::ALL
                .iter()
                .map(|c| (c.name(), p.probabilities[c.index()]))
                .collect();
            json!({
                "type": "Feature",
                "geometry": {"type": "Polygon", "coordinates": [ring]},
                "properties": {
                    "osm_id": s.osm_id,
                    "roof_shape": p.class().name(),
                    "probabilities": probabilities,
                    "confident": p.confidence() >= threshold,
                    "imagery_id": s.imagery_id,
                    "model_id": s.model_id,
                }
            })
        })
        .collect();
    let body = json!({
        "type": "FeatureCollection",
        "features": features,
        "imagery_attribution": roofs.imagery_attribution,
        "threshold": threshold,
    });
    Ok((
        [(axum::http::header::CONTENT_TYPE, "application/geo+json")],
        Json(body),
    )
        .into_response())
}

/// 503: jobs cannot run on this server, and why.
pub(super) fn classification_unavailable(why: &str) -> AppError {
    AppError::Unavailable {
        code: "classification_unavailable",
        detail: format!("roof classification is not available: {why}"),
        retry_after_secs: 3600,
    }
}

use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::{get, post};

use super::error::{ApiError, ApiResult};
use super::{Params, RestState, body_bytes, int_param, json_body, page, stored};
use crate::app::inference::{
    EnergyReportRequest, EnergyRequest, EvaluateRequest, InverseRequest, PredictRequest,
    SimulateRequest,
};
use crate::app::requests::parse_body;
use crate::app::uploads::BodyKind;

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/models", get(list).post(upload))
        .route("/v1/models/{id}", get(read).delete(remove))
        .route("/v1/models/{id}/checkpoint", get(checkpoint))
        .route("/v1/models/{id}/urdf", get(urdf))
        .route("/v1/models/{id}/rollout", get(rollout))
        .route("/v1/models/{id}/evaluate", post(evaluate))
        .route("/v1/models/{id}/predict", post(predict))
        .route("/v1/models/{id}/simulate", post(simulate))
        .route("/v1/models/{id}/energy", post(energy))
        .route("/v1/models/{id}/inverse-dynamics", post(inverse_dynamics))
        .route("/v1/models/{id}/energy-report", post(energy_report))
}

/// The model's energy report on a stored dataset, stored with the model.
async fn energy_report(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: EnergyReportRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.energy_report(&id, req).await?))
}

/// x' for a batch of states, at the model's step or the body's `dt`.
async fn predict(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: PredictRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.predict_json(&id, req).await?))
}

/// A rollout from x0 under a sequence of inputs, whole.
async fn simulate(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: SimulateRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.simulate_json(&id, req).await?))
}

/// The generalized force that gives accelerations at a batch of states, with its terms.
async fn inverse_dynamics(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: InverseRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.inverse_json(&id, req).await?))
}

/// T, V, E, the power of F and the split of the dynamics at a batch of states.
async fn energy(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: EnergyRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.energy_json(&id, req).await?))
}

/// The model's open-loop error against horizon on a trajectory dataset.
async fn evaluate(
    State(s): State<RestState>,
    Path(id): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let req: EvaluateRequest = parse_body(json_body(body, s.limit(BodyKind::Small))?)?;
    Ok(axum::Json(s.app.evaluate(&id, req).await?))
}

/// The model's replay of a dataset's trajectory beside the recording.
async fn rollout(
    State(s): State<RestState>,
    Path(id): Path<String>,
    p: Params,
) -> ApiResult<impl IntoResponse> {
    let dataset = p
        .get("dataset_id")
        .ok_or_else(|| ApiError::bad_request("dataset_id", "is required"))?;
    let index =
        int_param(&p, "index")?.ok_or_else(|| ApiError::bad_request("index", "is required"))?;
    let index = usize::try_from(index)
        .map_err(|_| ApiError::bad_request("index", format!("must be ≥ 0, got {index}")))?;
    // Out of usize's range is out of the particles' range too: the app names it alike.
    let particles = int_param(&p, "particles")?.map(|v| usize::try_from(v).unwrap_or(0));
    Ok(axum::Json(
        s.app.replay(&id, dataset, index, particles).await?,
    ))
}

/// A model file (`.gbx`, the format `checkpoint` returns) stored as it is: 201, or 200 with
/// the stored model when the same file was uploaded before.
async fn upload(
    State(s): State<RestState>,
    p: Params,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let limit = s.limit(BodyKind::Model);
    let bytes = body_bytes(body, limit)?;
    let model = s.app.upload_model(p.get("name").cloned(), Vec::from(bytes));
    Ok(stored(model.await?))
}

async fn list(State(s): State<RestState>, p: Params) -> ApiResult<impl IntoResponse> {
    let (items, next) = s
        .app
        .list_models(
            int_param(&p, "page_size")?,
            p.get("page_token").map(String::as_str),
        )
        .await?;
    Ok(page(items, next))
}

/// A model by its id, or by the id of the job that trained it (as gRPC reads it).
async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.model_with_coordinates(&id).await?))
}

async fn checkpoint(
    State(s): State<RestState>,
    Path(id): Path<String>,
) -> ApiResult<impl IntoResponse> {
    let file = s.app.model_file(&id).await?;
    let disposition = format!("attachment; filename=\"{id}.gbx\"");
    Ok((
        [
            (header::CONTENT_TYPE, "application/json".to_string()),
            (header::CONTENT_DISPOSITION, disposition),
        ],
        file,
    ))
}

/// The identified robot as URDF (409 when the model's template is not a URDF robot).
async fn urdf(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    let text = s.app.model_urdf(&id).await?;
    let disposition = format!("attachment; filename=\"{id}.urdf\"");
    Ok((
        [
            (header::CONTENT_TYPE, "application/xml".to_string()),
            (header::CONTENT_DISPOSITION, disposition),
        ],
        text,
    ))
}

async fn remove(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<StatusCode> {
    s.app.delete_model(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

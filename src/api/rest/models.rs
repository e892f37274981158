use axum::Router;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;
use serde_json::{Value, json};

use super::error::ApiResult;
use super::{Params, RestState, int_param, page};
use crate::store::ModelRow;

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/models", get(list))
        .route("/v1/models/{id}", get(read).delete(remove))
        .route("/v1/models/{id}/checkpoint", get(checkpoint))
}

/// The API view of a model: spec, dimensions, losses, physical parameters.
pub fn model_json(m: &ModelRow) -> Value {
    let report: Value = serde_json::from_str(&m.report).unwrap_or(Value::Null);
    let spec: Value = serde_json::from_str(&m.spec).unwrap_or(Value::Null);
    json!({
        "id": m.id,
        "job_id": m.job_id,
        "name": m.name,
        "spec": spec,
        "n": m.n,
        "m": m.m,
        "dt": m.dt,
        "metrics": {
            "epochs": report["epochs"],
            "train_loss": report["train_loss"],
            "val_loss": report["val_loss"],
            "best_epoch": report["best_epoch"],
            "best_val_loss": report["best_val_loss"],
            "seconds": report["seconds"],
            "samples_per_second": report["samples_per_second"],
        },
        "physical_parameters": report["physical_parameters"],
        "identifiable": report["identifiable"],
        "sha256": m.sha256,
        "created_at": m.created_at,
    })
}

async fn list(State(s): State<RestState>, p: Params) -> ApiResult<impl IntoResponse> {
    let (items, next) = s
        .app
        .list_models(
            int_param(&p, "page_size")?,
            p.get("page_token").map(String::as_str),
        )
        .await?;
    Ok(page(items.iter().map(model_json).collect(), next))
}

async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(model_json(&s.app.model(&id).await?)))
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

async fn remove(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<StatusCode> {
    s.app.delete_model(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

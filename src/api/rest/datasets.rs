use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;

use super::error::{ApiError, ApiResult};
use super::{Params, RestState, float_param, int_param, json_body, page};
use crate::app::datasets::Upload;

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/datasets", get(list).post(upload))
        .route("/v1/datasets/{id}", get(read).delete(remove))
}

async fn upload(
    State(s): State<RestState>,
    params: Params,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let limit = s.app.settings.max_body_bytes();
    let csv = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|ct| ct.starts_with("text/csv"));
    let upload = if csv {
        let bytes = body.map_err(|_| ApiError::too_large(limit))?;
        let text = String::from_utf8(bytes.to_vec())
            .map_err(|_| ApiError::bad_request("body", "CSV must be UTF-8"))?;
        Upload::Csv {
            text,
            dt: float_param(&params, "dt")?,
        }
    } else {
        Upload::Json(json_body(body, limit)?)
    };
    let (row, created) = s
        .app
        .upload_dataset(params.get("name").cloned(), upload)
        .await?;
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, axum::Json(row)))
}

async fn list(State(s): State<RestState>, p: Params) -> ApiResult<impl IntoResponse> {
    let (items, next) = s
        .app
        .list_datasets(
            int_param(&p, "page_size")?,
            p.get("page_token").map(String::as_str),
        )
        .await?;
    Ok(page(items, next))
}

async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.dataset(&id).await?))
}

async fn remove(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<StatusCode> {
    s.app.delete_dataset(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

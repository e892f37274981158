use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;

use super::error::{ApiError, ApiResult};
use super::{
    Params, RestState, body_bytes, float_param, int_param, json_body, page, stored_status,
};
use crate::app::datasets::Upload;
use crate::app::uploads::BodyKind;

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/datasets", get(list).post(upload))
        .route("/v1/datasets/{id}", get(read).delete(remove))
        .route("/v1/datasets/{id}/trajectories", get(trajectories))
}

/// The body's format: `content-type: text/csv` is CSV and `application/json` JSON; any other
/// (curl's `--data-binary` sends `application/x-www-form-urlencoded`) is told by its first
/// character: `{` is JSON, anything else CSV.
fn is_csv(headers: &HeaderMap, body: &[u8]) -> bool {
    let ct = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    if ct.starts_with("text/csv") {
        return true;
    }
    if ct.starts_with("application/json") {
        return false;
    }
    body.iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|&b| b != b'{')
}

async fn upload(
    State(s): State<RestState>,
    params: Params,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let limit = s.limit(BodyKind::Dataset);
    let dt = float_param(&params, "dt")?;
    let bytes = body_bytes(body, limit)?;
    let upload = if is_csv(&headers, &bytes) {
        let text = String::from_utf8(Vec::from(bytes))
            .map_err(|_| ApiError::bad_request("body", "CSV must be UTF-8"))?;
        Upload::Csv { text, dt }
    } else {
        let value = json_body(Ok(bytes), limit).map_err(|mut e| {
            e.message += "; a CSV upload is sent with content-type: text/csv (and ?dt=)";
            e
        })?;
        Upload::Json { value, dt }
    };
    let uploaded = s
        .app
        .upload_dataset(params.get("name").cloned(), upload)
        .await?;
    Ok((stored_status(uploaded.created), axum::Json(uploaded)))
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

async fn trajectories(
    State(s): State<RestState>,
    Path(id): Path<String>,
    p: Params,
) -> ApiResult<impl IntoResponse> {
    let page_size = int_param(&p, "page_size")?;
    let token = p.get("page_token").map(String::as_str);
    Ok(axum::Json(
        s.app.dataset_trajectories(&id, page_size, token).await?,
    ))
}

use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;

use super::error::{ApiError, ApiResult};
use super::{
    Params, RestState, body_bytes, bool_param, float_param, int_param, json_body, page,
    stored_status,
};
use crate::app::datasets::Upload;
use crate::app::uploads::BodyKind;
use crate::data::log::{DEFAULT_FIT, Fit, ImportOptions, Inputs, LogColumns, column_list};

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
    let upload = if params.contains_key("time") {
        log_upload(&params, bytes.to_vec())?
    } else if is_csv(&headers, &bytes) {
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

/// A robot's log (`?time=COL&q=COLS&u=COLS[&qdot=COLS][&qddot=COLS][&wrapped=COLS][&dt=S][&resample=true][&gap=5]
/// [&window=15][&order=3][&inputs=held]`, the CSV or Parquet body as `graybox import` reads it), allowed the memory its
/// body reserved (`BodyKind::cost`).
fn log_upload(params: &Params, bytes: Vec<u8>) -> ApiResult<Upload> {
    let list = |name: &str| params.get(name).map_or_else(Vec::new, |v| column_list(v));
    let count = |name: &str, default: usize| -> ApiResult<usize> {
        match int_param(params, name)? {
            None => Ok(default),
            Some(v) => usize::try_from(v)
                .map_err(|_| ApiError::bad_request(name, format!("must be ≥ 0, got {v}"))),
        }
    };
    let defaults = ImportOptions::default();
    let options = ImportOptions {
        dt: float_param(params, "dt")?,
        resample: bool_param(params, "resample")?,
        gap: float_param(params, "gap")?.unwrap_or(defaults.gap),
        fit: Fit {
            window: count("window", DEFAULT_FIT.window)?,
            order: count("order", DEFAULT_FIT.order)?,
        },
        wrapped: list("wrapped"),
        inputs: params
            .get("inputs")
            .map_or(Ok(Inputs::Linear), |v| Inputs::parse(v))?,
        smooth_inputs: bool_param(params, "smooth_inputs")?,
        memory: Some(BodyKind::Dataset.cost(bytes.len())),
    };
    let columns = LogColumns {
        time: params.get("time").cloned().unwrap_or_default(),
        q: list("q"),
        qdot: list("qdot"),
        qddot: list("qddot"),
        u: list("u"),
    };
    Ok(Upload::Log {
        bytes,
        columns,
        options,
    })
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

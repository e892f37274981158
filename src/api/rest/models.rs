use axum::Router;
use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;

use super::error::ApiResult;
use super::{Params, RestState, int_param, page};

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/models", get(list))
        .route("/v1/models/{id}", get(read).delete(remove))
        .route("/v1/models/{id}/checkpoint", get(checkpoint))
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

async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.model(&id).await?))
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

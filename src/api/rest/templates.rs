use axum::Router;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;

use super::error::ApiResult;
use super::{Params, RestState, body_bytes, int_param, page, stored};
use crate::app::uploads::BodyKind;

pub fn routes() -> Router<RestState> {
    Router::new()
        .route("/v1/templates", get(list).post(upload))
        .route("/v1/templates/{id}", get(read).delete(remove))
}

/// A template document (JSON, or a raw URDF as XML): 201, or 200 with the stored template when the same document was
/// uploaded before.
async fn upload(
    State(s): State<RestState>,
    headers: HeaderMap,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<impl IntoResponse> {
    let bytes = body_bytes(body, s.limit(BodyKind::Template))?;
    // A raw URDF is XML (application/xml, text/xml, or a +xml type).
    let xml = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(';').next().unwrap_or("").trim().ends_with("xml"));
    Ok(stored(s.app.upload_template(bytes, xml).await?))
}

async fn list(State(s): State<RestState>, p: Params) -> ApiResult<impl IntoResponse> {
    let (items, next) = s
        .app
        .list_templates(
            int_param(&p, "page_size")?,
            p.get("page_token").map(String::as_str),
        )
        .await?;
    Ok(page(items, next))
}

async fn read(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<impl IntoResponse> {
    Ok(axum::Json(s.app.template(&id).await?))
}

async fn remove(State(s): State<RestState>, Path(id): Path<String>) -> ApiResult<StatusCode> {
    s.app.delete_template(&id).await?;
    Ok(StatusCode::NO_CONTENT)
}

use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use axum::routing::get;
use serde_json::json;

use super::RestState;
use super::error::{ApiError, ApiResult};

pub fn routes() -> Router<RestState> {
    probes().route(
        "/openapi.json",
        get(|| async { axum::Json(crate::api::openapi::document()) }),
    )
}

/// Liveness, readiness and the Prometheus metrics: what every graybox process answers.
pub fn probes() -> Router<RestState> {
    Router::new()
        .route(
            "/healthz",
            get(|| async { axum::Json(json!({"status": "ok"})) }),
        )
        .route("/readyz", get(ready))
        .route("/metrics", get(metrics))
}

/// Ready when the database (and the object store, with `--blobs`) answer within a couple of
/// seconds; the message names the one that did not.
async fn ready(State(s): State<RestState>) -> ApiResult<impl IntoResponse> {
    s.app.ready().await.map_err(|e| {
        tracing::warn!(error = %e, "not ready");
        ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "unavailable",
            format!("not ready: {}", e.public_message()),
        )
    })?;
    Ok(axum::Json(json!({"status": "ready"})))
}

async fn metrics(State(s): State<RestState>) -> ApiResult<impl IntoResponse> {
    Ok((
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        s.app.metrics_text().await,
    ))
}

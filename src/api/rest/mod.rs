//! The REST API (axum): routers per resource, one error shape, auth, request metrics, the
//! browser's security headers (`web/mod.rs`) on every answer.

mod admission;
mod datasets;
pub mod error;
mod jobs;
mod models;
mod ops;
mod templates;

use std::collections::HashMap;
use std::time::Instant;

use axum::Router;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};

use crate::app::App;
use crate::app::uploads::BodyKind;
use crate::app::views::Stored;
use error::{ApiError, ApiResult};

#[derive(Clone)]
pub struct RestState {
    pub app: App,
}

impl RestState {
    /// The largest body a route of `kind` takes.
    fn limit(&self, kind: BodyKind) -> usize {
        kind.limit(&self.app.settings)
    }
}

/// The whole REST router; tests call it with `oneshot` or over a socket.
pub fn router(app: App) -> Router {
    let state = RestState { app };
    Router::new()
        .merge(datasets::routes())
        .merge(jobs::routes())
        .merge(models::routes())
        .merge(templates::routes())
        .merge(ops::routes())
        .merge(crate::api::web::routes())
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "not_found", "no such route") })
        .method_not_allowed_fallback(|| async {
            ApiError::new(
                StatusCode::METHOD_NOT_ALLOWED,
                "invalid_argument",
                "method not allowed on this route",
            )
        })
        .layer(middleware::from_fn_with_state(
            state.clone(),
            admission::admit_body,
        ))
        .layer(middleware::from_fn_with_state(state.clone(), authorize))
        .layer(middleware::from_fn_with_state(state.clone(), record))
        // Outermost, so that the answers of the layers inside (401, 413, 503) carry them too.
        .layer(middleware::map_response(crate::api::web::security_headers))
        // `admit_body` cuts every body off at its route's limit (`BodyKind::of`).
        .layer(DefaultBodyLimit::disable())
        .with_state(state)
}

/// A worker process's only listener (`graybox worker --health`): `/healthz`, `/readyz` and
/// `/metrics`, no resources and no token (it carries no data).
pub fn health_router(app: App) -> Router {
    Router::new()
        .merge(ops::probes())
        .fallback(|| async { ApiError::new(StatusCode::NOT_FOUND, "not_found", "no such route") })
        .with_state(RestState { app })
}

async fn authorize(State(s): State<RestState>, req: Request, next: Next) -> Response {
    let Some(token) = s.app.settings.token() else {
        return next.run(req).await;
    };
    let read = matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    let path = req.uri().path();
    let open = matches!(path, "/healthz" | "/readyz") || crate::api::web::is_open(path);
    if open || (read && !s.app.settings.auth_reads) {
        return next.run(req).await;
    }
    let given = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok());
    let ok = crate::api::listen::bearer_matches(given, token);
    if ok {
        next.run(req).await
    } else {
        ApiError::unauthorized().into_response()
    }
}

async fn record(State(s): State<RestState>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    let method = req.method().to_string();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or("unmatched".to_string(), |p| p.as_str().to_string());
    let resp = next.run(req).await;
    s.app.telemetry.record_request(
        &method,
        &route,
        resp.status().as_u16(),
        start.elapsed().as_secs_f64(),
    );
    resp
}

/// Query parameters as strings, parsed by the handlers so that every bad value gets the
/// error shape with its field named.
pub type Params = axum::extract::Query<HashMap<String, String>>;

/// 201 Created for what this request stored, 200 OK for what an earlier one had.
pub fn stored_status(created: bool) -> StatusCode {
    if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    }
}

/// A stored item as the response: its status ([`stored_status`]) and the item.
pub fn stored<T: serde::Serialize>(s: Stored<T>) -> (StatusCode, axum::Json<T>) {
    (stored_status(s.created), axum::Json(s.item))
}

pub fn int_param(p: &HashMap<String, String>, name: &str) -> ApiResult<Option<i64>> {
    p.get(name)
        .map(|v| {
            v.parse::<i64>()
                .map_err(|_| ApiError::bad_request(name, format!("'{v}' is not an integer")))
        })
        .transpose()
}

pub fn float_param(p: &HashMap<String, String>, name: &str) -> ApiResult<Option<f64>> {
    p.get(name)
        .map(|v| {
            v.parse::<f64>()
                .map_err(|_| ApiError::bad_request(name, format!("'{v}' is not a number")))
        })
        .transpose()
}

/// `true` or `false` (absent: false).
pub fn bool_param(p: &HashMap<String, String>, name: &str) -> ApiResult<bool> {
    match p.get(name).map(String::as_str) {
        None | Some("false") => Ok(false),
        Some("true") => Ok(true),
        Some(v) => Err(ApiError::bad_request(
            name,
            format!("'{v}' is not true or false"),
        )),
    }
}

/// A request body's bytes: over the limit is 413, any other failure to read it 400.
pub fn body_bytes(
    body: Result<axum::body::Bytes, axum::extract::rejection::BytesRejection>,
    limit: usize,
) -> ApiResult<axum::body::Bytes> {
    body.map_err(|e| {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::too_large(limit)
        } else {
            ApiError::bad_request("body", e.body_text())
        }
    })
}

/// A JSON body: malformed JSON is a 400 naming "body"; an oversized body a 413.
pub fn json_body(
    body: Result<axum::body::Bytes, axum::extract::rejection::BytesRejection>,
    limit: usize,
) -> ApiResult<serde_json::Value> {
    let bytes = body_bytes(body, limit)?;
    serde_json::from_slice(&bytes)
        .map_err(|e| ApiError::bad_request("body", format!("malformed JSON: {e}")))
}

/// A list page: `{"items": [...], "next_page_token": ...}`.
pub fn page<T: serde::Serialize>(
    items: Vec<T>,
    next: Option<String>,
) -> axum::Json<serde_json::Value> {
    axum::Json(serde_json::json!({ "items": items, "next_page_token": next }))
}

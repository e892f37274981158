//! Request bodies in flight under one memory budget: an upload reserves what reading and
//! parsing its body will cost before a byte of it is read, or gets 503 with `Retry-After`.
//! Without this, 50 concurrent 200 MB uploads each held their body and its parse at once.

use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::RestState;
use super::error::{ApiError, RETRY_AFTER_SECS};
use crate::app::uploads::BodyKind;

/// Admits a request's body under the budget before the handler reads it: a declared
/// `Content-Length` over the route's limit is 413 at once; else the body's cost (declared
/// length, or the limit when none is declared, times the kind's cost per byte) is reserved
/// until the response is ready, or the request gets 503 with `Retry-After`.
///
/// This is the one place a route's body limit is set: the body is cut off at it whatever
/// its transfer encoding. A chunked body declares no length, and a limit set per group of
/// routes once let the small routes under the model upload's group read 64 MiB while the
/// budget held 64 KiB for them.
pub async fn admit_body(State(s): State<RestState>, req: Request, next: Next) -> Response {
    let settings = &s.app.settings;
    let kind = BodyKind::of(req.method().as_str(), req.uri().path());
    let limit = kind.unwrap_or(BodyKind::Small).limit(settings);
    let req = req.map(|body| Body::new(http_body_util::Limited::new(body, limit)));
    let Some(kind) = kind else {
        return next.run(req).await;
    };
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    if declared.is_some_and(|n| n > limit) {
        return ApiError::too_large(limit).into_response();
    }
    let cost = kind.cost(declared.unwrap_or(limit));
    let Some(permit) = s.app.memory.try_reserve(cost) else {
        let message = format!(
            "request bodies and data being read use the in-flight budget \
             (--max-inflight-body-mb {}); retry in {RETRY_AFTER_SECS} s",
            settings.max_inflight_body_mb
        );
        return ApiError::busy(message).into_response();
    };
    let response = next.run(req).await;
    drop(permit);
    response
}

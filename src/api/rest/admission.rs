//! Request bodies in flight under one memory budget: an upload reserves what reading and
//! parsing its body will cost before a byte of it is read, or gets 503 with `Retry-After`.
//! Without this, 50 concurrent 200 MB uploads each held their body and its parse at once.

use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

use super::RestState;
use super::error::ApiError;
use crate::app::uploads::BodyKind;

/// Seconds a refused upload is told to wait: about what one large upload takes to parse.
const RETRY_AFTER_SECS: u64 = 2;

/// The body limit of routes that take no document.
pub const SMALL_BODY_LIMIT: usize = crate::app::uploads::SMALL_BODY;

/// Budget units: 1 MiB each (a semaphore counts in u32).
const UNIT: usize = 1 << 20;

/// The budget every body in flight shares, in MiB.
pub struct BodyBudget {
    permits: Arc<Semaphore>,
}

impl BodyBudget {
    pub fn new(bytes: usize) -> Self {
        let units = (bytes / UNIT).clamp(1, Semaphore::MAX_PERMITS);
        Self {
            permits: Arc::new(Semaphore::new(units)),
        }
    }

    /// `cost` bytes of the budget until the permit drops, if they are free now.
    fn try_reserve(&self, cost: usize) -> Option<OwnedSemaphorePermit> {
        let units = u32::try_from(cost.div_ceil(UNIT).max(1)).unwrap_or(u32::MAX);
        self.permits.clone().try_acquire_many_owned(units).ok()
    }
}

/// Admits a request's body under the budget before the handler reads it: a declared
/// `Content-Length` over the route's limit is 413 at once; else the body's cost (declared
/// length, or the limit when none is declared, times the kind's cost per byte) is reserved
/// until the response is ready, or the request gets 503 with `Retry-After`.
pub async fn admit_body(State(s): State<RestState>, req: Request, next: Next) -> Response {
    let Some(kind) = BodyKind::of(req.method().as_str(), req.uri().path()) else {
        return next.run(req).await;
    };
    let settings = &s.app.settings;
    let limit = kind.limit(settings);
    let declared = req
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    if declared.is_some_and(|n| n > limit) {
        return ApiError::too_large(limit).into_response();
    }
    let cost = kind.cost(declared.unwrap_or(limit));
    let Some(permit) = s.bodies.try_reserve(cost) else {
        let message = format!(
            "request bodies in flight use the upload budget (--max-inflight-body-mb {}); \
             retry in {RETRY_AFTER_SECS} s",
            settings.max_inflight_body_mb
        );
        let mut response =
            ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", message).into_response();
        response
            .headers_mut()
            .insert(header::RETRY_AFTER, RETRY_AFTER_SECS.into());
        return response;
    };
    let response = next.run(req).await;
    drop(permit);
    response
}

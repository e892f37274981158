//! One error body for every 4xx/5xx: `{"error": {"code", "message", "field"?}}`, its
//! message and field cut to a bound (`api/echo.rs`).

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde_json::json;

use crate::api::echo::{FIELD_LIMIT, MESSAGE_LIMIT, bounded};
use crate::error::Error;

/// An error as the REST API reports it.
#[derive(Debug)]
pub struct ApiError {
    pub status: StatusCode,
    pub code: &'static str,
    pub message: String,
    pub field: Option<String>,
    /// Seconds a client is told to wait before it retries (`Retry-After`).
    pub retry_after: Option<u64>,
}

/// Seconds a request refused for a shared bound (memory, waiting calls) is told to wait.
pub const RETRY_AFTER_SECS: u64 = 2;

impl ApiError {
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self {
            status,
            code,
            message: message.into(),
            field: None,
            retry_after: None,
        }
    }

    /// 503 with `Retry-After`: a bound the requests share was reached, not a fault.
    pub fn busy(message: impl Into<String>) -> Self {
        Self {
            retry_after: Some(RETRY_AFTER_SECS),
            ..Self::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", message)
        }
    }

    pub fn bad_request(field: &str, message: impl Into<String>) -> Self {
        Self {
            field: Some(field.into()),
            ..Self::new(StatusCode::BAD_REQUEST, "invalid_argument", message)
        }
    }

    pub fn unauthorized() -> Self {
        Self::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "a valid 'Authorization: Bearer <token>' header is required",
        )
    }

    pub fn too_large(limit: usize) -> Self {
        Self::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "payload_too_large",
            format!("the body is larger than the limit of {} bytes", limit),
        )
    }
}

impl From<Error> for ApiError {
    fn from(e: Error) -> Self {
        let message = e.public_message();
        let detail = e.to_string();
        let (status, code, field) = match e {
            Error::Invalid { field, message } => {
                return Self {
                    field: Some(field),
                    ..Self::new(StatusCode::BAD_REQUEST, "invalid_argument", message)
                };
            }
            Error::Unprocessable { field, message } => {
                return Self {
                    field: Some(field),
                    ..Self::new(StatusCode::UNPROCESSABLE_ENTITY, "unprocessable", message)
                };
            }
            Error::NotFound(_) => (StatusCode::NOT_FOUND, "not_found", None),
            Error::ResourceExhausted(_) => {
                (StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large", None)
            }
            Error::Conflict(_) | Error::FailedPrecondition(_) | Error::Cancelled => {
                (StatusCode::CONFLICT, "conflict", None)
            }
            Error::DeadlineExceeded(_) => (StatusCode::GATEWAY_TIMEOUT, "deadline_exceeded", None),
            Error::Busy(_) => return Self::busy(message),
            Error::Storage(_) => {
                tracing::error!(error = %detail, "storage unavailable");
                (StatusCode::SERVICE_UNAVAILABLE, "unavailable", None)
            }
            Error::Internal(_) | Error::Training(_) | Error::Io(_) | Error::Corrupt { .. } => {
                tracing::error!(error = %detail, "internal error");
                (StatusCode::INTERNAL_SERVER_ERROR, "internal", None)
            }
        };
        Self {
            status,
            code,
            message,
            field,
            retry_after: None,
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let message = bounded(self.message, MESSAGE_LIMIT);
        let mut err = json!({"code": self.code, "message": message});
        if let Some(f) = self.field {
            err["field"] = json!(bounded(f, FIELD_LIMIT));
        }
        let mut response = (self.status, Json(json!({ "error": err }))).into_response();
        if let Some(secs) = self.retry_after {
            (response.headers_mut()).insert(axum::http::header::RETRY_AFTER, secs.into());
        }
        response
    }
}

pub type ApiResult<T> = Result<T, ApiError>;

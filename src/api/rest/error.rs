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
}

impl ApiError {
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self {
            status,
            code,
            message: message.into(),
            field: None,
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
        (self.status, Json(json!({ "error": err }))).into_response()
    }
}

pub type ApiResult<T> = Result<T, ApiError>;

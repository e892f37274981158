//! Domain ↔ protobuf conversions and the error → status mapping (exhaustive: a new error
//! variant must decide its code here).

use tonic::Status;

use super::pb;
use crate::api::echo::{MESSAGE_LIMIT, bounded};
use crate::app::views::Model;
use crate::error::Error;

impl From<Error> for Status {
    fn from(e: Error) -> Self {
        // The message quotes the field and what the caller sent: bounded like REST's.
        let msg = bounded(e.to_string(), MESSAGE_LIMIT);
        match e {
            Error::Invalid { .. } | Error::Unprocessable { .. } => Status::invalid_argument(msg),
            Error::NotFound(_) => Status::not_found(msg),
            Error::FailedPrecondition(_) | Error::Conflict(_) => Status::failed_precondition(msg),
            Error::ResourceExhausted(_) => Status::resource_exhausted(msg),
            Error::Cancelled => Status::cancelled(msg),
            Error::Storage(_) => Status::unavailable(msg),
            Error::DeadlineExceeded(_) => Status::deadline_exceeded(msg),
            Error::Internal(_) | Error::Training(_) | Error::Io(_) | Error::Corrupt { .. } => {
                Status::internal(msg)
            }
        }
    }
}

pub fn array(shape: &[usize], data: Vec<f64>) -> pb::Array {
    pb::Array {
        shape: shape.iter().map(|&s| s as u64).collect(),
        data,
    }
}

/// The array's values and shape, or an INVALID_ARGUMENT naming the missing field.
pub fn take(field: &str, a: Option<pb::Array>) -> Result<(Vec<f64>, Vec<u64>), Status> {
    a.map(|a| (a.data, a.shape))
        .ok_or_else(|| Status::invalid_argument(format!("{field}: is required")))
}

pub fn model_info(m: &Model) -> pb::ModelInfo {
    pb::ModelInfo {
        id: m.id.clone(),
        job_id: m.job_id.clone().unwrap_or_default(),
        name: m.name.clone(),
        n: m.n as u64,
        m: m.m as u64,
        dt: m.dt,
        spec_json: m.spec.to_string(),
        metrics_json: m.metrics.to_string(),
        created_at: m.created_at.clone(),
    }
}

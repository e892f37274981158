//! Domain ↔ protobuf conversions and the error → status mapping (exhaustive: a new error
//! variant must decide its code here).

use tonic::Status;

use super::pb;
use crate::api::echo::{MESSAGE_LIMIT, bounded};
use crate::app::views::ModelView;
use crate::array::Array;
use crate::control::linalg::Mat;
use crate::control::plan::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, EnsembleCost, Method, PlanRequest, time_limit_in,
};
use crate::error::Error;

/// `?` for the library's results in a gRPC handler: `app.call().await.or_status()?`. (The
/// error type is the inference core's and `Status` is tonic's, so no `From` between them may
/// be written here.)
pub trait OrStatus<T> {
    fn or_status(self) -> Result<T, Status>;
}

impl<T> OrStatus<T> for crate::error::Result<T> {
    fn or_status(self) -> Result<T, Status> {
        self.map_err(status)
    }
}

/// The library's error as a gRPC status, its code by the one mapping (`Error::code`,
/// ARCHITECTURE.md's table).
pub fn status(e: Error) -> Status {
    // The message quotes the field and what the caller sent: bounded like REST's.
    let msg = bounded(e.public_message(), MESSAGE_LIMIT);
    if let Error::Storage(detail) = &e {
        tracing::error!(error = %detail, "storage unavailable");
    }
    Status::new(tonic::Code::from(e.code().0), msg)
}

impl From<Array> for pb::Array {
    fn from(a: Array) -> Self {
        pb::Array {
            shape: a.shape,
            data: a.data,
        }
    }
}

impl From<pb::Array> for Array {
    fn from(a: pb::Array) -> Self {
        Array {
            shape: a.shape,
            data: a.data,
        }
    }
}

/// The array, or an INVALID_ARGUMENT naming the missing field.
pub fn take(field: &str, a: Option<pb::Array>) -> Result<Array, Status> {
    a.map(Array::from)
        .ok_or_else(|| Status::invalid_argument(format!("{field}: is required")))
}

/// A Plan call as the core's request: absent options take the planner's defaults, an empty
/// bound is none (the model's effort limits then apply), and the core checks the rest
/// against the model and the limits.
pub fn plan_request(r: pb::PlanRequest) -> Result<PlanRequest, Status> {
    // The message's field for a missing array, the math's name for a bad one (as TVLQR's).
    let matrix = |field: &str, name: &str, a: Option<pb::Array>| -> Result<Mat, Status> {
        Mat::from_array(name, take(field, a)?).or_status()
    };
    let bound = |v: Vec<f64>| (!v.is_empty()).then_some(v);
    Ok(PlanRequest {
        x0: r.x0,
        goal: r.goal,
        // Beyond usize: over any horizon limit, which the core's check names.
        horizon: usize::try_from(r.horizon).unwrap_or(usize::MAX),
        q: matrix("q", "Q", r.q)?,
        r: matrix("r", "R", r.r)?,
        qf: matrix("qf", "Qf", r.qf)?,
        u_min: bound(r.u_min),
        u_max: bound(r.u_max),
        u_init: (r.u_init)
            .map(|a| matrix("u_init", "u_init", Some(a)))
            .transpose()?,
        x_init: (r.x_init)
            .map(|a| matrix("x_init", "x_init", Some(a)))
            .transpose()?,
        x_min: bound(r.x_min),
        x_max: bound(r.x_max),
        method: Method::parse(&r.method).or_status()?,
        ensemble_cost: EnsembleCost::parse(&r.ensemble_cost).or_status()?,
        max_iterations: r
            .max_iterations
            .map_or(DEFAULT_MAX_ITERATIONS, |v| v as usize),
        tolerance: r.tolerance.unwrap_or(DEFAULT_TOLERANCE),
        restarts: r.restarts as usize,
        seed: r.seed,
        time_limit: time_limit_in(r.time_limit_ms),
    })
}

pub fn model_info(m: &ModelView) -> pb::ModelInfo {
    pb::ModelInfo {
        id: m.id.clone(),
        job_id: m.job_id.clone().unwrap_or_default(),
        name: m.name.clone(),
        n: m.n as u64,
        nq: m.nq as u64,
        nv: m.nv as u64,
        m: m.m as u64,
        dt: m.dt,
        spec_json: m.spec.to_string(),
        metrics_json: m.metrics.to_string(),
        created_at: m.created_at.clone(),
    }
}

//! Control from trained models (docs/control.md): finite-horizon TVLQR in f64, the feedback
//! policy it defines, and trajectory optimisation (iLQR with control bounds).

pub mod boxqp;
pub mod dircol;
pub mod ensemble;
pub mod linalg;
pub mod plan;
mod plan_request;
pub mod policy;
pub mod tvlqr;

use crate::error::Result;
use dircol::Continuous;
use plan::{Dynamics, Method, Plan, PlanRequest};

/// A plan by the request's method: iLQR (`plan::plan`) or direct collocation
/// (`dircol::plan`).
pub fn make_plan<S: Dynamics + Continuous>(
    sys: &S,
    req: &PlanRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Plan> {
    match req.method {
        Method::Ilqr => plan::plan(sys, req, stop),
        Method::Dircol => dircol::plan(sys, req, stop),
    }
}

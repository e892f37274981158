//! Control from trained models (docs/control.md): finite-horizon TVLQR in f64, the feedback
//! policy it defines, and trajectory optimisation (iLQR with control bounds).

pub mod boxqp;
pub mod dircol;
pub mod linalg;
pub mod plan;
mod plan_request;
pub mod policy;
pub mod tvlqr;

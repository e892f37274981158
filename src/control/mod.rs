//! Control from trained models (design.md §2): finite-horizon TVLQR in f64 and the feedback
//! policy it defines.

pub mod linalg;
pub mod policy;
pub mod tvlqr;

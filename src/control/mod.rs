//! Control from trained models (design.md §2): finite-horizon TVLQR in f64.

pub mod linalg;
pub mod tvlqr;

//! Direct collocation (DIRCOL): a plan's knot states and inputs as the decision variables of
//! a sparse nonlinear program whose constraints make them a solution of the model's
//! continuous dynamics ẋ = f(x, u) = (q̇, q̈(q, q̇, u)) (docs/control.md#direct-collocation).
//! This module holds the transcription: the variables' layout, the collocation defects and
//! their sparse Jacobian from f's exact Jacobians at each point.

pub mod transcription;

use super::linalg::Mat;

/// A system's continuous dynamics, for collocation: f and its Jacobians at a batch of points.
pub trait Continuous {
    fn nx(&self) -> usize;
    fn m(&self) -> usize;
    /// ẋ for `[B, nx]` states and `[B, m]` inputs, row-major.
    fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64>;
    /// ∂f/∂x `[nx, nx]` and ∂f/∂u `[nx, m]` at each row.
    fn derivative_jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>);
}

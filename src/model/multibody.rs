//! URDF models in training on the multibody algorithms (docs/robots.md#training-by-the-adjoint):
//! each integrator stage's q̈ = FD(q, q̇, τ; π) is one node of the step's tape
//! (`physics::tape::forward_dynamics`), forward by the articulated-body algorithm and backward
//! by forward dynamics' adjoint. The template's assembly of M(q) and V(q) stays selectable as
//! the reference that node is tested against (`Model::assembled`).

use super::{Model, fused};

impl Model {
    /// The same model on the template's M(q) and V(q) assembly instead of the multibody
    /// algorithms: the reference training's node is tested against, and a benchmark's
    /// baseline.
    pub fn assembled(mut self) -> Self {
        [self.step, self.timed, self.torque] = fused::ops(&self.config, &self.params, false);
        self
    }

    /// Whether q̈ comes from the multibody algorithms.
    pub fn is_multibody(&self) -> bool {
        self.step.is_multibody()
    }
}

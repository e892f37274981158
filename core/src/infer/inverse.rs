//! Inverse dynamics (docs/energy.md, "Inverse dynamics"): the generalized force τ the inputs
//! must supply for an acceleration q̈ at (q, q̇),
//!
//!   τ = M(q) q̈ + c(q, q̇) + ∇V(q) − F(q, q̇, 0),
//!
//! F at zero input being the model's passive forces (damping, friction, a formula's unforced
//! part), with the same terms Energy gives. Where the inputs enter as F = u + passive (a URDF
//! robot, the built-in templates) τ is the input that produces q̈: a controller's
//! feed-forward torque, and what a torque sensor or a drive's current measures.

use super::{Energies, Evaluator};
use crate::error::{Error, Result};

/// A batch's τ `[B, nv]` and its terms (`terms.applied`: F(q, q̇, 0); its named parts, the
/// passive ones only).
#[derive(Debug, Clone, PartialEq)]
pub struct InverseDynamics {
    pub tau: Vec<f64>,
    pub terms: Energies,
}

impl Evaluator {
    /// τ for `[B, nq + nv]` states and `[B, nv]` accelerations, or `None` when `stop` says so
    /// (polled every state).
    pub fn inverse_dynamics_until(
        &self,
        x: &[f64],
        qdd: &[f64],
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<InverseDynamics>> {
        let (nx, nv, m) = (self.config.nx(), self.config.nv(), self.config.m);
        if !x.len().is_multiple_of(nx) {
            return Err(Error::invalid(
                "x",
                format!("{} values are not rows of {nx} (q, q̇)", x.len()),
            ));
        }
        let rows = x.len() / nx;
        if qdd.len() != rows * nv {
            return Err(Error::invalid(
                "qdd",
                format!(
                    "{} values for {rows} states: one row of {nv} accelerations per state",
                    qdd.len()
                ),
            ));
        }
        let u = vec![0.0; rows * m];
        let Some(mut terms) = self.terms_until(x, &u, Some(qdd), stop)? else {
            return Ok(None);
        };
        // The input's part is zero here by construction: τ is what the inputs must supply.
        terms.parts.retain(|p| p.name != "input");
        let tau = (0..rows * nv)
            .map(|i| terms.inertial[i] + terms.coriolis[i] + terms.gravity[i] - terms.applied[i])
            .collect();
        Ok(Some(InverseDynamics { tau, terms }))
    }
}

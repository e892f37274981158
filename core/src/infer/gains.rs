//! TVLQR gains on the model's exact linearization (an ensemble's mean dynamics').

use super::{Evaluator, finite_rows};
use crate::control::linalg::Mat;
use crate::control::tvlqr::{Gains, tvlqr};
use crate::error::{Error, Result};

impl Evaluator {
    /// TVLQR gains along a nominal `x̄ [(T+1), nq + nv]`, `ū [T, m]` (defects ignored), on
    /// tangent-space deviations: Q and Qf are 2nv × 2nv, K m × 2nv.
    pub fn tvlqr(&self, xbar: &[f64], ubar: &[f64], q: &Mat, r: &Mat, qf: &Mat) -> Result<Gains> {
        self.tvlqr_until(xbar, ubar, [q, r, qf], &|| false)
    }

    /// [`Evaluator::tvlqr`], or `Error::Cancelled` when `stop` says so before a chunk of the
    /// linearization (most of the work).
    pub fn tvlqr_until(
        &self,
        xbar: &[f64],
        ubar: &[f64],
        [q, r, qf]: [&Mat; 3],
        stop: &dyn Fn() -> bool,
    ) -> Result<Gains> {
        let (nx, ndx, m) = (self.config.nx(), self.config.ndx(), self.config.m);
        let t = ubar.len() / m;
        let (a, b) = self
            .linearize_until(&xbar[..t * nx], ubar, stop)
            .ok_or(Error::Cancelled)?;
        finite_rows("x_bar", "linearization", &a, ndx * ndx)?;
        finite_rows("x_bar", "linearization", &b, ndx * m)?;
        let (a, b) = self.jacobians(a, b);
        tvlqr(&a, &b, q, r, qf)
    }

    /// Flat `[T, 2nv, 2nv]` and `[T, 2nv, m]` Jacobians as matrices.
    pub(super) fn jacobians(&self, a: Vec<f64>, b: Vec<f64>) -> (Vec<Mat>, Vec<Mat>) {
        let (nx, m) = (self.config.ndx(), self.config.m);
        (
            a.chunks(nx * nx)
                .map(|a| Mat::new(nx, nx, a.to_vec()))
                .collect(),
            b.chunks(nx * m)
                .map(|b| Mat::new(nx, m, b.to_vec()))
                .collect(),
        )
    }
}

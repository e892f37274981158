//! Trajectory optimisation on a served model (`control::plan`): the request checked against
//! the model and the limits, then solved as heavy work that stops at the caller's deadline or
//! when the caller goes away.

use std::time::Instant;

use super::{Cost, members_held};
use crate::app::App;
use crate::control::plan::{EnsembleCost, Method, Plan, PlanRequest, check_horizon, validate};
use crate::error::{Error, Result};
use crate::infer::limits::Pass;

impl App {
    /// A plan from x0 toward the goal on the model, with TVLQR gains along it. With no input
    /// bound given, the model's effort limits (a URDF's) bound the inputs.
    pub async fn plan(
        &self,
        id: &str,
        req: PlanRequest,
        deadline: Option<Instant>,
    ) -> Result<Plan> {
        let eval = self.evaluator(id).await?;
        let horizon = u64::try_from(req.horizon).unwrap_or(u64::MAX);
        check_horizon(horizon, self.settings.max_plan_horizon)?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let req = req.with_effort_limits(&eval.effort_limits());
        validate(&req, nx, m)?;
        let t = req.horizon;
        // The members' average cost plans on all of them stacked: K·nx states.
        let k = eval.member_count();
        let nx = match req.ensemble_cost {
            EnsembleCost::Mean => k * nx,
            EnsembleCost::MeanDynamics => nx,
        };
        // Jacobians, the backward pass's matrices and gains, the line search's ten
        // trajectories, the best start's, the returned plan and its message. Restarts add
        // time, not memory (one start is kept besides the current one); the time is the
        // deadline's to bound, which the solver checks at every time step.
        let per_step = match req.method {
            Method::Ilqr => 8 * (4 * (nx * nx + nx * m) + 11 * (nx + m) + 2 * m * nx),
            Method::Dircol => dircol_bytes_per_interval(nx, m),
        };
        let iterations = req.max_iterations + 1;
        self.admit(
            "horizon",
            &Cost {
                response_bytes: 8 * ((t + 1) * nx + t * m + t * m * nx + iterations),
                memory_bytes: t * per_step
                    + t.min(2 * eval.chunk_states(Pass::Linearize))
                        * eval.work_bytes_per_state(Pass::Linearize)
                    + members_held(&eval, 8 * (t + 1) * (nx * nx + nx * m)),
            },
        )?;
        // The solver polls `stop` at every time step of every pass (`control::plan`).
        self.heavy_until("plan", deadline, move |stop| match eval.plan(&req, stop) {
            Err(Error::Cancelled) => None,
            done => Some(done),
        })
        .await?
    }
}

/// Direct collocation's memory per interval, all of which lives until the plan is answered:
/// f's Jacobians at three points, the defect Jacobian as triplets (this iterate's and the
/// last's), the learned curvature's block, the QP's matrices in clarabel (P and A, A's
/// scaled copy) and its KKT system with the factor's fill (about twice the band of one
/// interval's rows: variables, defects, bounds), and the interior point's ~20 vectors.
/// Measured on the double pendulum: a peak of 146 MB at T = 4000, 36.5 KB an interval; this
/// gives 38 KB there.
fn dircol_bytes_per_interval(nx: usize, m: usize) -> usize {
    let jacobian = nx * (5 * nx + 2 * m + 1);
    let (block, kkt) = (3 * nx + m, 4 * nx + 3 * m);
    8 * 3 * (nx * nx + nx * m)
        + 2 * 24 * jacobian
        + 8 * block * block
        + 12 * (block * block + 2 * jacobian)
        + 16 * 3 * kkt * kkt
        + 8 * 20 * kkt
}

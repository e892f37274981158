//! Trajectory optimisation on a served model (`control::plan`): the request checked against
//! the model and the limits, then solved as heavy work that stops at the caller's deadline or
//! when the caller goes away.

use std::time::{Duration, Instant};

use super::{Array, Cost, rows, square};
use crate::app::App;
use crate::control::plan::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_TOLERANCE, Plan, PlanRequest, check_horizon, plan,
};
use crate::error::{Error, Result};
use crate::infer::limits::Pass;

/// A Plan call as it arrives: vectors, arrays with their shapes, and the options (`None`:
/// the default).
pub struct PlanCall {
    pub x0: Vec<f64>,
    pub goal: Vec<f64>,
    pub horizon: u64,
    pub q: Array,
    pub r: Array,
    pub qf: Array,
    /// Empty (both): the model's effort limits (a URDF's), else unbounded.
    pub u_min: Vec<f64>,
    pub u_max: Vec<f64>,
    pub u_init: Option<Array>,
    pub max_iterations: Option<u32>,
    pub tolerance: Option<f64>,
    pub restarts: u32,
    pub seed: u64,
    /// 0: none.
    pub time_limit_ms: u64,
}

impl App {
    /// A plan from x0 toward the goal on the model, with TVLQR gains along it.
    pub async fn plan(&self, id: &str, call: PlanCall, deadline: Option<Instant>) -> Result<Plan> {
        let eval = self.evaluator(id).await?;
        let (nx, m) = (2 * eval.config.n, eval.config.m);
        let req = self
            .plan_request(call, nx, m)?
            .with_effort_limits(&eval.effort_limits());
        crate::control::plan::validate(&req, nx, m)?;
        let t = req.horizon;
        // Jacobians, the backward pass's matrices and gains, the line search's ten
        // trajectories, the best start's, the returned plan and its message. Restarts add
        // time, not memory (one start is kept besides the current one); the time is the
        // deadline's to bound, which the solver checks at every time step.
        let per_step = 8 * (4 * (nx * nx + nx * m) + 11 * (nx + m) + 2 * m * nx);
        let iterations = req.max_iterations + 1;
        self.admit(
            "horizon",
            &Cost {
                response_bytes: 8 * ((t + 1) * nx + t * m + t * m * nx + iterations),
                memory_bytes: t * per_step
                    + t.min(2 * eval.chunk_states(Pass::Linearize))
                        * eval.work_bytes_per_state(Pass::Linearize),
            },
        )?;
        // The solver polls `stop` at every time step of every pass (`control::plan`).
        self.heavy_until("plan", deadline, move |stop| {
            match plan(eval.as_ref(), &req, stop) {
                Err(Error::Cancelled) => None,
                done => Some(done),
            }
        })
        .await?
    }

    /// The call's arrays checked against the model's dimensions and the service's limits.
    fn plan_request(&self, c: PlanCall, nx: usize, m: usize) -> Result<PlanRequest> {
        let horizon = check_horizon(c.horizon, self.settings.max_plan_horizon)?;
        let bound = |name: &str, v: Vec<f64>| -> Result<Option<Vec<f64>>> {
            match v.len() {
                0 => Ok(None),
                k if k == m => Ok(Some(v)),
                k => Err(Error::invalid(
                    name,
                    format!("expected {m} values (or none), got {k}"),
                )),
            }
        };
        let u_init = match c.u_init {
            None => None,
            Some((u, shape)) => {
                let t = rows("u_init", &shape, &u, m)?.rows;
                if t != horizon {
                    return Err(Error::invalid(
                        "u_init",
                        format!("needs {horizon} rows (the horizon), got {t}"),
                    ));
                }
                Some(u)
            }
        };
        Ok(PlanRequest {
            x0: c.x0,
            goal: c.goal,
            horizon,
            q: square("Q", &c.q.1, &c.q.0, nx)?,
            r: square("R", &c.r.1, &c.r.0, m)?,
            qf: square("Qf", &c.qf.1, &c.qf.0, nx)?,
            u_min: bound("u_min", c.u_min)?,
            u_max: bound("u_max", c.u_max)?,
            u_init,
            max_iterations: c
                .max_iterations
                .map_or(DEFAULT_MAX_ITERATIONS, |v| v as usize),
            tolerance: c.tolerance.unwrap_or(DEFAULT_TOLERANCE),
            restarts: c.restarts as usize,
            seed: c.seed,
            time_limit: (c.time_limit_ms > 0)
                .then(|| Instant::now().checked_add(Duration::from_millis(c.time_limit_ms)))
                .flatten(),
        })
    }
}

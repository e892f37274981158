//! Trajectory optimisation on a served model (`control::plan`): the request checked against
//! the model and the limits, then solved as heavy work that stops at the caller's deadline or
//! when the caller goes away.

use std::time::Instant;

use super::Class;
use crate::app::App;
use crate::control::plan::{Plan, PlanRequest, check_horizon, validate};
use crate::error::{Error, Result};

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
        let req = req.with_effort_limits(&eval.effort_limits());
        validate(&req, (eval.config.nx(), eval.config.ndx()), eval.config.m)?;
        self.admit_call(&eval.plan_cost(&req))?;
        // The solver polls `stop` at every time step of every pass (`control::plan`).
        self.heavy_until(Class::Long, "plan", deadline, move |stop| {
            match eval.plan(&req, stop) {
                Err(Error::Cancelled) => None,
                done => Some(done),
            }
        })
        .await?
    }
}

//! What a plan is asked for, and its checks: every field validated with an error naming it.

use std::time::Instant;

use super::linalg::Mat;
use super::tvlqr::check_weight;
use crate::error::{Error, Result};

pub const DEFAULT_MAX_ITERATIONS: usize = 200;
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Extra starts a request may ask for. Each is a whole optimisation, so the count multiplies
/// the call's time (memory keeps one start besides the best): 2³² − 1 of them once held a
/// permit for days. The experiments take 8; a thousand leaves room to explore.
pub const MAX_RESTARTS: usize = 1000;
/// The longest horizon the service (`--max-plan-horizon`) and `graybox plan` accept by
/// default: the plan's arrays grow with it (a billion steps aborted on allocation).
pub const DEFAULT_MAX_PLAN_HORIZON: usize = 10_000;

/// How a plan is made (docs/control.md): iLQR on the one-step map, or direct collocation on
/// the continuous dynamics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Method {
    #[default]
    Ilqr,
    Dircol,
}

impl Method {
    pub const NAMES: [&str; 2] = ["ilqr", "dircol"];

    pub fn name(self) -> &'static str {
        match self {
            Method::Ilqr => "ilqr",
            Method::Dircol => "dircol",
        }
    }

    /// From its name; empty is the default (iLQR). An unknown one names the field.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "" | "ilqr" => Ok(Method::Ilqr),
            "dircol" => Ok(Method::Dircol),
            other => Err(Error::invalid(
                "method",
                format!("unknown method {other:?}; expected one of ilqr, dircol"),
            )),
        }
    }
}

/// What a plan on an ensemble minimizes (`control::ensemble`); a single model has one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum EnsembleCost {
    /// The cost on the mean dynamics (the members' average next state), as every call uses.
    #[default]
    MeanDynamics,
    /// The members' average cost, every member rolling out the same inputs.
    Mean,
}

impl EnsembleCost {
    /// From its name; empty is the default (the mean dynamics). An unknown one names the field.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "" | "mean_dynamics" => Ok(EnsembleCost::MeanDynamics),
            "mean" => Ok(EnsembleCost::Mean),
            other => Err(Error::invalid(
                "ensemble_cost",
                format!("unknown ensemble cost {other:?}; expected mean_dynamics or mean"),
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            EnsembleCost::MeanDynamics => "mean_dynamics",
            EnsembleCost::Mean => "mean",
        }
    }
}

/// What to plan: the one request type that `graybox plan`, the gRPC `Plan` call and the lab
/// build. Arrays are row-major; `u_init` is `[T, m]`.
#[derive(Debug, Clone)]
pub struct PlanRequest {
    pub x0: Vec<f64>,
    pub goal: Vec<f64>,
    pub horizon: usize,
    pub q: Mat,
    pub r: Mat,
    pub qf: Mat,
    pub u_min: Option<Vec<f64>>,
    pub u_max: Option<Vec<f64>>,
    pub u_init: Option<Mat>,
    /// Collocation's initial states `[T+1, nx]` (its first row is x0's place and is replaced
    /// by x0); absent, the rollout of the initial inputs. iLQR refuses it.
    pub x_init: Option<Mat>,
    /// Collocation's state bounds, `[nx]` each, on every knot and midpoint after x0 (±∞: none
    /// on that coordinate). iLQR refuses them.
    pub x_min: Option<Vec<f64>>,
    pub x_max: Option<Vec<f64>>,
    pub method: Method,
    /// On an ensemble: the mean dynamics' cost or the members' average cost.
    pub ensemble_cost: EnsembleCost,
    /// 0: no iteration; the plan is the rollout of the best start, with its gains.
    pub max_iterations: usize,
    pub tolerance: f64,
    /// At most [`MAX_RESTARTS`].
    pub restarts: usize,
    pub seed: u64,
    /// Return the best plan so far at this instant, with `converged = false`.
    pub time_limit: Option<Instant>,
}

/// A plan's time limit `ms` milliseconds from now, as every caller gives it (0: none).
pub fn time_limit_in(ms: u64) -> Option<Instant> {
    (ms > 0)
        .then(|| Instant::now().checked_add(std::time::Duration::from_millis(ms)))
        .flatten()
}

impl PlanRequest {
    /// From `x0` to `goal` in `horizon` steps under the cost weights, with the defaults of
    /// everything else: inputs unbounded, a zero initial guess, no restarts, no time limit.
    pub fn new(x0: Vec<f64>, goal: Vec<f64>, horizon: usize, [q, r, qf]: [Mat; 3]) -> Self {
        Self {
            x0,
            goal,
            horizon,
            q,
            r,
            qf,
            u_min: None,
            u_max: None,
            u_init: None,
            x_init: None,
            x_min: None,
            x_max: None,
            method: Method::Ilqr,
            ensemble_cost: EnsembleCost::MeanDynamics,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            tolerance: DEFAULT_TOLERANCE,
            restarts: 0,
            seed: 0,
            time_limit: None,
        }
    }
}

impl PlanRequest {
    /// With no bound given on either side, the robot's: |u_k| ≤ effort_k where its actuator
    /// has a limit (a URDF's `<limit effort>`), unbounded where not. A bound given is the
    /// caller's choice and stands alone.
    pub fn with_effort_limits(mut self, effort: &[Option<f64>]) -> Self {
        if self.u_min.is_none() && self.u_max.is_none() && effort.iter().any(Option::is_some) {
            let hi: Vec<f64> = (effort.iter())
                .map(|e| e.unwrap_or(f64::INFINITY))
                .collect();
            self.u_min = Some(hi.iter().map(|h| -h).collect());
            self.u_max = Some(hi);
        }
        self
    }
}

/// `horizon` within `max` (the `--max-plan-horizon` limit), as a length; over it the request
/// is refused before anything is allocated for it.
pub fn check_horizon(horizon: u64, max: usize) -> Result<usize> {
    match usize::try_from(horizon) {
        Ok(h) if h <= max => Ok(h),
        _ => Err(Error::ResourceExhausted(format!(
            "horizon {horizon} is over the limit of {max} (--max-plan-horizon)"
        ))),
    }
}

/// Every field of a request checked, each error naming it: states (x0, the goal, x_init,
/// the state bounds) nx wide, the state weights ndx × ndx (they weigh deviations x ⊖ g).
pub fn validate(req: &PlanRequest, (nx, ndx): (usize, usize), m: usize) -> Result<()> {
    let finite = |name: &str, v: &[f64], len: usize| -> Result<()> {
        if v.len() != len {
            return Err(Error::invalid(
                name,
                format!("expected {len} values, got {}", v.len()),
            ));
        }
        match v.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(Error::invalid(
                name,
                format!("value {i} is not finite ({})", v[i]),
            )),
            None => Ok(()),
        }
    };
    finite("x0", &req.x0, nx)?;
    finite("goal", &req.goal, nx)?;
    if req.horizon == 0 {
        return Err(Error::invalid("horizon", "must be at least 1"));
    }
    check_weight("Q", &req.q, ndx, false)?;
    check_weight("Qf", &req.qf, ndx, false)?;
    check_weight("R", &req.r, m, true)?;
    if let Some(lo) = &req.u_min {
        check_bound("u_min", lo, m)?;
    }
    if let Some(hi) = &req.u_max {
        check_bound("u_max", hi, m)?;
    }
    if let (Some(lo), Some(hi)) = (&req.u_min, &req.u_max)
        && let Some(i) = (0..m).find(|&i| lo[i] > hi[i])
    {
        return Err(Error::invalid(
            "u_min",
            format!("u_min[{i}] = {} is above u_max[{i}] = {}", lo[i], hi[i]),
        ));
    }
    if let Some(u) = &req.u_init {
        if u.rows != req.horizon || u.cols != m {
            return Err(Error::invalid(
                "u_init",
                format!(
                    "needs [{}, {m}] (the horizon, m), got [{}, {}]",
                    req.horizon, u.rows, u.cols
                ),
            ));
        }
        finite("u_init", &u.data, req.horizon.saturating_mul(m))?;
    }
    check_state_bounds(req, nx)?;
    if let Some(x) = &req.x_init {
        if req.method != Method::Dircol {
            return Err(only_dircol("x_init"));
        }
        if x.rows != req.horizon.saturating_add(1) || x.cols != nx {
            return Err(Error::invalid(
                "x_init",
                format!(
                    "needs [{}, {nx}] (the horizon + 1, nq + nv), got [{}, {}]",
                    req.horizon.saturating_add(1),
                    x.rows,
                    x.cols
                ),
            ));
        }
        finite("x_init", &x.data, x.rows.saturating_mul(nx))?;
    }
    if !(req.tolerance.is_finite() && req.tolerance >= 0.0) {
        return Err(Error::invalid("tolerance", "must be a finite number ≥ 0"));
    }
    if req.restarts > MAX_RESTARTS {
        return Err(Error::invalid(
            "restarts",
            format!("must be at most {MAX_RESTARTS}, got {}", req.restarts),
        ));
    }
    Ok(())
}

/// Only collocation has the states as variables: iLQR's are the rollout of its inputs.
fn only_dircol(field: &str) -> Error {
    Error::invalid(
        field,
        "only direct collocation (method dircol) takes initial states or state bounds; \
         iLQR's states are the rollout of its inputs",
    )
}

/// x_min and x_max: collocation's, each [nx], ordered, and x0 within them.
fn check_state_bounds(req: &PlanRequest, nx: usize) -> Result<()> {
    for (name, bound) in [("x_min", &req.x_min), ("x_max", &req.x_max)] {
        if let Some(b) = bound {
            if req.method != Method::Dircol {
                return Err(only_dircol(name));
            }
            check_bound(name, b, nx)?;
        }
    }
    let lo = req
        .x_min
        .clone()
        .unwrap_or_else(|| vec![f64::NEG_INFINITY; nx]);
    let hi = req.x_max.clone().unwrap_or_else(|| vec![f64::INFINITY; nx]);
    if let Some(i) = (0..nx).find(|&i| lo[i] > hi[i]) {
        return Err(Error::invalid(
            "x_min",
            format!("x_min[{i}] = {} is above x_max[{i}] = {}", lo[i], hi[i]),
        ));
    }
    match (0..nx).find(|&i| !(lo[i]..=hi[i]).contains(&req.x0[i])) {
        Some(i) => Err(Error::invalid(
            "x0",
            format!(
                "x0[{i}] = {} is outside the state bounds [{}, {}]",
                req.x0[i], lo[i], hi[i]
            ),
        )),
        None => Ok(()),
    }
}

/// A bound may be ±∞ on a component (unbounded there) but not NaN.
fn check_bound(name: &str, v: &[f64], m: usize) -> Result<()> {
    if v.len() != m {
        return Err(Error::invalid(
            name,
            format!("expected {m} values, got {}", v.len()),
        ));
    }
    match v.iter().position(|x| x.is_nan()) {
        Some(i) => Err(Error::invalid(name, format!("value {i} is NaN"))),
        None => Ok(()),
    }
}

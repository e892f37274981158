//! Trajectory optimisation on a model's discrete one-step map (docs/control.md#trajectory-optimisation):
//!
//! ```text
//! minimize J = Σ_{t<T} (x_t − g)ᵀQ(x_t − g) + u_tᵀR u_t + (x_T − g)ᵀQ_f(x_T − g)   (no ½)
//! subject to x_{t+1} = f(x_t, u_t), x_0 given, u_min ≤ u_t ≤ u_max
//! ```
//!
//! Method: iLQR with control bounds (Tassa, Mansard & Todorov 2014, "Control-limited
//! differential dynamic programming"). Why this is the default and direct collocation
//! (`control::dircol`) the option: it needs only f and its exact Jacobians (A_t, B_t), which
//! the f64 evaluator already gives (`Linearize`, dual numbers), every iterate is a rollout of
//! the model and so dynamically feasible by construction, and the bounds become a box QP of m
//! variables per step (`boxqp`) rather than an NLP over all states. The backward pass is a Riccati recursion on the quadratic model of
//! the cost-to-go with a Levenberg–Marquardt term μI on Q_uu (raised when a Q_uu is not
//! positive definite or no step improves, lowered after a success, starting at 0 so that a
//! linear-quadratic problem is solved exactly in one iteration). Regularizing Q_uu rather
//! than V_xx (Tassa 2012's state-space variant) matters on long horizons of an unstable
//! system: there V_xx grows like ‖A‖^{2T}, and μI added to it made the 200-step swing-up's
//! backward pass overflow (measured: stuck at J = 1995 vs converged at J = 521). The forward pass tries ten
//! step sizes α = 1, ½, …, 2⁻⁹ in one batched rollout and keeps the cheapest one that lowers
//! J; a trial whose rollout goes non-finite costs +∞ and is never chosen.

mod backward;
mod forward;

use std::time::Instant;

pub use super::plan_request::{
    DEFAULT_MAX_ITERATIONS, DEFAULT_MAX_PLAN_HORIZON, DEFAULT_TOLERANCE, EnsembleCost,
    MAX_RESTARTS, Method, PlanRequest, check_horizon, time_limit_in, validate,
};

use super::linalg::Mat;
use super::tvlqr::{Gains, NOMINAL, tvlqr};
use crate::error::{Error, Result};
use crate::rng::Rng;

/// The system a plan is made for: its one-step map on a batch of rows, and the map's
/// Jacobians along a trajectory.
pub trait Dynamics {
    fn nx(&self) -> usize;
    fn m(&self) -> usize;
    /// x′ for `[B, nx]` states and `[B, m]` inputs, row-major.
    fn step(&self, x: &[f64], u: &[f64]) -> Vec<f64>;
    /// A_t and B_t at each row of `[T, nx]` states and `[T, m]` inputs: the one-step map's
    /// Jacobians in the tangent space, x′ ⊖ x̄′ = A (x ⊖ x̄) + B (u − ū), `[ndx, ndx]` and
    /// `[ndx, m]`.
    fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>);
    /// The width of a state's deviation x ⊖ x̄ (2nv; nx when every joint is one number).
    fn ndx(&self) -> usize {
        self.nx()
    }
    /// x1 ⊖ x0 for one state each: the deviation every cost, gain and feedback reads.
    fn difference(&self, x0: &[f64], x1: &[f64]) -> Vec<f64> {
        x1.iter().zip(x0).map(|(a, b)| a - b).collect()
    }
    /// One state in coordinates where every joint is one number (`ndx` wide; a rotation by its
    /// angle), and back: collocation's variables on a space of nq ≠ nv (`dircol::chart`).
    fn chart_of(&self, x: &[f64]) -> Vec<f64> {
        x.to_vec()
    }
    fn state_at(&self, c: &[f64]) -> Vec<f64> {
        c.to_vec()
    }
}

/// A plan: states `[T+1, nx]`, inputs `[T, m]`, TVLQR gains along it with the request's
/// weights, its cost, the cost of the initial guess and after every accepted iteration
/// (non-increasing for iLQR; collocation's merit, not its cost, decreases), whether it
/// converged, and the method that made it. Collocation's states satisfy the continuous
/// dynamics up to `constraint_violation` (its largest defect) and depart from the one-step
/// map's rollout of its inputs by up to `rollout_deviation`; both are 0 for iLQR, whose plan
/// is that rollout.
#[derive(Debug, Clone)]
pub struct Plan {
    pub x: Vec<f64>,
    pub u: Vec<f64>,
    pub gains: Gains,
    pub cost: f64,
    pub costs: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
    pub goal_error: f64,
    pub method: Method,
    pub constraint_violation: f64,
    pub rollout_deviation: f64,
    /// An ensemble's: the members' standard deviation of each state `[T+1, nx]` along the
    /// inputs (`control::ensemble`).
    pub x_std: Option<Vec<f64>>,
}

const STEP_SIZES: usize = 10;
/// Time steps linearized at once: enough for the evaluator's two threads to pay off (it
/// splits from 32 rows), few enough to take milliseconds between checks of `stop`.
const LINEARIZE_ROWS: usize = 256;
const MU_MIN: f64 = 1e-6;
const MU_MAX: f64 = 1e10;

pub(super) struct Bounds {
    pub(super) lo: Vec<f64>,
    pub(super) hi: Vec<f64>,
}

impl Bounds {
    /// Either side unbounded where not given.
    pub(super) fn new(lo: &Option<Vec<f64>>, hi: &Option<Vec<f64>>, len: usize) -> Self {
        Self {
            lo: lo.clone().unwrap_or_else(|| vec![f64::NEG_INFINITY; len]),
            hi: hi.clone().unwrap_or_else(|| vec![f64::INFINITY; len]),
        }
    }

    pub(super) fn clamp(&self, u: &mut [f64]) {
        let m = self.lo.len();
        for (i, v) in u.iter_mut().enumerate() {
            *v = v.max(self.lo[i % m]).min(self.hi[i % m]);
        }
    }
}

/// One candidate solution: inputs, the states they give, its cost, and the Jacobians
/// (A_t, B_t) along it once computed (a rejected step reuses them; the gains of the returned
/// plan too).
#[derive(Clone)]
pub(super) struct Trajectory {
    pub(super) x: Vec<f64>,
    pub(super) u: Vec<f64>,
    pub(super) cost: f64,
    jacobians: Option<(Vec<Mat>, Vec<Mat>)>,
}

impl Trajectory {
    pub(super) fn new(x: Vec<f64>, u: Vec<f64>, cost: f64) -> Self {
        Self {
            x,
            u,
            cost,
            jacobians: None,
        }
    }
}

/// The planner for one request on one system.
pub(super) struct Planner<'a, D: Dynamics> {
    pub(super) sys: &'a D,
    pub(super) req: &'a PlanRequest,
    pub(super) bounds: Bounds,
    pub(super) stop: &'a dyn Fn() -> bool,
}

/// A locally optimal plan (the best of `1 + restarts` starts), or an error naming the field
/// of a bad request. `stop` is polled before every start, iteration and time step of a pass
/// (an atomic load and a clock read: a step of the model costs far more), because a pass
/// that never checked it once held its thread for billions of starts: when it says so the
/// call ends with `Error::Cancelled` (a caller's deadline or cancellation). The request's own
/// time limit instead returns the best plan so far.
///
/// This is iLQR whatever `req.method` says; `control::make_plan` follows the method.
pub fn plan(sys: &impl Dynamics, req: &PlanRequest, stop: &dyn Fn() -> bool) -> Result<Plan> {
    validate(req, (sys.nx(), sys.ndx()), sys.m())?;
    let p = Planner::new(sys, req, stop);
    let mut rng = Rng::derive(req.seed, 0x91_A2);
    let mut best: Option<(Trajectory, Vec<f64>, bool)> = None;
    for start in 0..=req.restarts {
        p.check()?;
        let u0 = p.initial_guess(start, &mut rng);
        let (t, costs, converged) = p.optimize(u0)?;
        if best.as_ref().is_none_or(|b| t.cost < b.0.cost) {
            best = Some((t, costs, converged));
        }
        if p.out_of_time() {
            break;
        }
    }
    let (t, costs, converged) = best.expect("at least one start");
    if !t.cost.is_finite() {
        // Every start's cost is +∞ (a finite one would have been kept). Returned, it read as
        // a plan, or its gains overflowed and the error blamed R.
        return Err(p.not_finite(&t));
    }
    p.finish(t, costs, converged)
}

impl<'a, D: Dynamics> Planner<'a, D> {
    pub(super) fn new(sys: &'a D, req: &'a PlanRequest, stop: &'a dyn Fn() -> bool) -> Self {
        Planner {
            sys,
            req,
            bounds: Bounds::new(&req.u_min, &req.u_max, sys.m()),
            stop,
        }
    }

    pub(super) fn check(&self) -> Result<()> {
        if (self.stop)() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }

    pub(super) fn out_of_time(&self) -> bool {
        self.req.time_limit.is_some_and(|t| Instant::now() >= t)
    }

    /// Start 0 is `u_init` (zeros by default); restart k draws every input uniformly within the
    /// bounds when both are given, else from N(0, σ²) with σ the largest |u_init| (1 when
    /// u_init is zero); all clipped to the bounds.
    pub(super) fn initial_guess(&self, start: usize, rng: &mut Rng) -> Vec<f64> {
        let (t, m) = (self.req.horizon, self.sys.m());
        let given = (self.req.u_init.as_ref()).map_or_else(|| vec![0.0; t * m], |u| u.data.clone());
        let mut u = if start == 0 {
            given
        } else {
            let sigma = given.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let sigma = if sigma > 0.0 { sigma } else { 1.0 };
            (0..t * m)
                .map(|k| {
                    let (lo, hi) = (self.bounds.lo[k % m], self.bounds.hi[k % m]);
                    if lo.is_finite() && hi.is_finite() {
                        rng.uniform_in(lo, hi)
                    } else {
                        sigma * rng.normal()
                    }
                })
                .collect()
        };
        self.bounds.clamp(&mut u);
        u
    }

    /// (x_s ⊖ g)ᵀ W (x_s ⊖ g), W = Q before the horizon and Q_f at it.
    fn state_cost(&self, x: &[f64], s: usize) -> f64 {
        let nx = self.sys.nx();
        let w = if s == self.req.horizon {
            &self.req.qf
        } else {
            &self.req.q
        };
        quadratic(w, self.off_goal(&x[s * nx..(s + 1) * nx]))
    }

    /// x ⊖ g.
    pub(super) fn off_goal(&self, x: &[f64]) -> Vec<f64> {
        self.sys.difference(&self.req.goal, x)
    }

    /// u_sᵀ R u_s.
    fn input_cost(&self, u: &[f64], s: usize) -> f64 {
        let m = self.sys.m();
        quadratic(&self.req.r, u[s * m..(s + 1) * m].to_vec())
    }

    pub(super) fn cost(&self, x: &[f64], u: &[f64]) -> f64 {
        let t = self.req.horizon;
        let j = (0..t)
            .map(|s| self.state_cost(x, s) + self.input_cost(u, s))
            .sum::<f64>()
            + self.state_cost(x, t);
        if j.is_finite() { j } else { f64::INFINITY }
    }

    /// What made `t`'s cost non-finite: its first state that is not finite (the model
    /// diverged), else its first cost term that overflowed.
    pub(super) fn not_finite(&self, t: &Trajectory) -> Error {
        let (nx, horizon) = (self.sys.nx(), self.req.horizon);
        let starts = match self.req.restarts {
            0 => "the initial guess".to_string(),
            r => format!("the initial guess and all {r} restarts"),
        };
        let first_bad =
            t.x.chunks(nx)
                .enumerate()
                .find_map(|(s, x)| x.iter().position(|v| !v.is_finite()).map(|i| (s, i)));
        if let Some((s, i)) = first_bad {
            // The coordinate that went non-finite was often ordinary a step before: show the
            // one that was growing.
            let before = &t.x[(s - 1) * nx..s * nx];
            let (j, big) = before.iter().enumerate().fold((0, 0.0f64), |m, (j, v)| {
                if v.abs() > m.1.abs() { (j, *v) } else { m }
            });
            return Error::invalid(
                "x0",
                format!(
                    "the model's state went non-finite at step {s} of {horizon} (x_{s}[{i}] = {}; \
                     the step before, its largest entry was x_{}[{j}] = {big:e}): from x0 the \
                     model diverges under {starts}. Try a shorter horizon, bounds on u, or an \
                     x0 within the data's range",
                    t.x[s * nx + i],
                    s - 1
                ),
            );
        }
        let input = (0..horizon).find(|&s| !self.input_cost(&t.u, s).is_finite());
        let state = (0..=horizon).find(|&s| !self.state_cost(&t.x, s).is_finite());
        match (state, input) {
            (Some(s), i) if i.is_none_or(|i| s <= i) => Error::invalid(
                "x0",
                format!(
                    "the plan's cost is not finite: (x_{s} − goal)ᵀ{}(x_{s} − goal) overflows f64 \
                     (x0 differs from the goal by up to {:e}); states this far from the goal \
                     cannot be weighed",
                    if s == horizon { "Q_f" } else { "Q" },
                    self.req
                        .x0
                        .iter()
                        .zip(&self.req.goal)
                        .fold(0.0f64, |m, (x, g)| m.max((x - g).abs()))
                ),
            ),
            (_, Some(s)) => Error::invalid(
                "u_init",
                format!("the plan's cost is not finite: u_{s}ᵀR u_{s} overflows f64"),
            ),
            // The terms are finite but their sum is not.
            _ => Error::invalid(
                "x0",
                "the plan's cost is not finite: its sum overflows f64; x0 is too far from the goal",
            ),
        }
    }

    /// A_t and B_t along `t`, computed once per trajectory, in pieces so that `stop` is
    /// heard within one (10⁴ steps at once took ~0.6 s).
    fn linearized<'t>(&self, t: &'t mut Trajectory) -> Result<&'t (Vec<Mat>, Vec<Mat>)> {
        let (nx, m, horizon) = (self.sys.nx(), self.sys.m(), self.req.horizon);
        if t.jacobians.is_none() {
            let (mut a, mut b) = (Vec::with_capacity(horizon), Vec::with_capacity(horizon));
            let pieces = t.x[..horizon * nx].chunks(LINEARIZE_ROWS * nx);
            for (x, u) in pieces.zip(t.u.chunks(LINEARIZE_ROWS * m)) {
                self.check()?;
                let (pa, pb) = self.sys.linearize(x, u);
                a.extend(pa);
                b.extend(pb);
            }
            t.jacobians = Some((a, b));
        }
        Ok(t.jacobians.as_ref().expect("just computed"))
    }

    /// iLQR from `u0`: the trajectory, its costs and whether it converged.
    fn optimize(&self, u0: Vec<f64>) -> Result<(Trajectory, Vec<f64>, bool)> {
        let mut cur = self.rollout(u0)?;
        let mut costs = vec![cur.cost];
        let mut mu = 0.0f64;
        let mut ks: Vec<Vec<f64>> = vec![vec![0.0; self.sys.m()]; self.req.horizon];
        for _ in 0..self.req.max_iterations {
            self.check()?;
            if self.out_of_time() || !cur.cost.is_finite() {
                return Ok((cur, costs, false));
            }
            self.linearized(&mut cur)?;
            let (a, b) = cur.jacobians.as_ref().expect("just computed");
            let Some(back) = self.backward(&cur, a, b, mu, &ks)? else {
                mu = (mu * 10.0).max(MU_MIN);
                if mu > MU_MAX {
                    return Ok((cur, costs, false));
                }
                continue;
            };
            // The quadratic model's predicted decrease of a full step: when it is within the
            // tolerance the plan is a (local) optimum.
            if back.expected <= self.req.tolerance * cur.cost.abs().max(f64::MIN_POSITIVE) {
                return Ok((cur, costs, true));
            }
            match self.line_search(&cur, &back)? {
                Some(next) => {
                    let decrease = (cur.cost - next.cost) / cur.cost.abs().max(f64::MIN_POSITIVE);
                    ks = back.k;
                    cur = next;
                    costs.push(cur.cost);
                    mu = if mu <= MU_MIN { 0.0 } else { mu / 10.0 };
                    if decrease < self.req.tolerance {
                        return Ok((cur, costs, true));
                    }
                }
                None => {
                    mu = (mu * 10.0).max(MU_MIN);
                    if mu > MU_MAX {
                        // No step lowers the cost even as a tiny gradient step: a local minimum.
                        return Ok((cur, costs, true));
                    }
                }
            }
        }
        Ok((cur, costs, false))
    }

    /// The plan to return: TVLQR gains along it with the request's weights.
    pub(super) fn finish(
        &self,
        mut t: Trajectory,
        costs: Vec<f64>,
        converged: bool,
    ) -> Result<Plan> {
        let (nx, horizon) = (self.sys.nx(), self.req.horizon);
        let (a, b) = self.linearized(&mut t)?;
        let bad = |m: &Mat| m.data.iter().any(|v| !v.is_finite());
        if let Some(s) = (0..horizon).find(|&s| bad(&a[s]) || bad(&b[s])) {
            return Err(Error::invalid(
                "x0",
                format!(
                    "the model's Jacobians are not finite at step {s} of the plan from x0 \
                     (x_{s} = {:?}): no gains exist along it",
                    &t.x[s * nx..(s + 1) * nx]
                ),
            ));
        }
        let gains = tvlqr(a, b, &self.req.q, &self.req.r, &self.req.qf).map_err(|e| match e {
            // The plan's own states are the nominal: they lead back to where it started.
            Error::Invalid { field, message } if field == NOMINAL => {
                Error::invalid("x0", format!("along the plan from x0, {message}"))
            }
            e => e,
        })?;
        let goal_error = norm(&self.off_goal(&t.x[horizon * nx..]));
        Ok(Plan {
            iterations: costs.len() - 1,
            cost: t.cost,
            x: t.x,
            u: t.u,
            gains,
            costs,
            converged: converged && !self.out_of_time(),
            goal_error,
            method: Method::Ilqr,
            constraint_violation: 0.0,
            rollout_deviation: 0.0,
            x_std: None,
        })
    }
}

/// ‖d‖₂.
pub fn norm(d: &[f64]) -> f64 {
    d.iter().map(|v| v.powi(2)).sum::<f64>().sqrt()
}

/// dᵀ W d.
fn quadratic(w: &Mat, d: Vec<f64>) -> f64 {
    let wd = w.mul(&Mat::new(d.len(), 1, d.clone()));
    d.iter().zip(&wd.data).map(|(a, b)| a * b).sum()
}

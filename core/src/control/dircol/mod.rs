//! Direct collocation (DIRCOL): a plan's knot states, inputs and midpoint states as the
//! decision variables of a sparse nonlinear program whose constraints make them a solution of
//! the model's continuous dynamics ẋ = f(x, u) = (q̇, q̈(q, q̇, u))
//! (docs/control.md#direct-collocation). `transcription` lays the program out, `sqp` solves
//! it with `qp`'s subproblems; this module makes the starts and the answer.

mod chart;
mod hessian;
mod qp;
mod sqp;
pub mod transcription;
mod triplets;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pub use sqp::DEFECT_TOLERANCE;

use self::qp::Until;
use self::sqp::Run;
use self::transcription::Layout;
use super::linalg::Mat;
use super::plan::{Bounds, Dynamics, Method, Plan, PlanRequest, Planner, Trajectory, validate};
use crate::error::{Error, Result};
use crate::rng::Rng;

/// A system's continuous dynamics, for collocation: f and its Jacobians at a batch of points.
pub trait Continuous {
    fn nx(&self) -> usize;
    fn m(&self) -> usize;
    /// The time step of the system's one-step map: collocation's interval.
    fn dt(&self) -> f64;
    /// ẋ for `[B, nx]` states and `[B, m]` inputs, row-major.
    fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64>;
    /// ∂f/∂x `[nx, nx]` and ∂f/∂u `[nx, m]` at each row.
    fn derivative_jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>);
}

/// Σ over the bounded states after x0 of how far each lies outside its bounds, and the
/// largest such distance.
fn outside(states: &Bounds, l: &Layout, z: &[f64]) -> (f64, f64) {
    let (mut sum, mut worst) = (0.0f64, 0.0f64);
    for at in l.free_states() {
        for i in 0..l.nx {
            let v = z[at + i];
            let out = (v - states.hi[i]).max(states.lo[i] - v).max(0.0);
            sum += out;
            worst = worst.max(out);
        }
    }
    (sum, worst)
}

/// The collocation of one request on one system; iLQR's planner lends it the request's
/// bounds, initial inputs, cost, rollout and the answer's gains.
pub(super) struct Collocation<'a, S: Dynamics + Continuous> {
    sys: &'a S,
    req: &'a PlanRequest,
    layout: Layout,
    h: f64,
    /// On every state after x0 (±∞ where none).
    states: Bounds,
    planner: Planner<'a, S>,
}

/// A locally optimal collocated plan (the best of `1 + restarts` starts: the feasible one of
/// least cost, else the least infeasible), or an error naming the field of a bad request.
/// `stop` ends the call with `Error::Cancelled` as for iLQR; the request's time limit returns
/// the best plan so far. Both are heard inside a QP solve too, through a thread that polls
/// `stop` every millisecond while the plan runs.
pub fn plan<S: Dynamics + Continuous>(
    sys: &S,
    req: &PlanRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Plan> {
    validate(req, (Dynamics::nx(sys), sys.ndx()), Dynamics::m(sys))?;
    if sys.ndx() != Dynamics::nx(sys) {
        return chart::plan(sys, req, stop);
    }
    collocate(sys, req, stop)
}

/// Collocation of a checked request on a system whose every joint is one number.
fn collocate<S: Dynamics + Continuous>(
    sys: &S,
    req: &PlanRequest,
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<Plan> {
    let c = Collocation {
        sys,
        req,
        layout: Layout {
            nx: Dynamics::nx(sys),
            m: Dynamics::m(sys),
            intervals: req.horizon,
        },
        h: sys.dt(),
        states: Bounds::new(&req.x_min, &req.x_max, Dynamics::nx(sys)),
        planner: Planner::new(sys, req, stop),
    };
    let until = Until {
        cancel: Arc::new(AtomicBool::new(false)),
        time_limit: req.time_limit,
    };
    let finished = AtomicBool::new(false);
    std::thread::scope(|s| {
        let watcher = s.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                if stop() {
                    until.cancel.store(true, Ordering::Relaxed);
                    return;
                }
                std::thread::park_timeout(Duration::from_millis(1));
            }
        });
        let result = c.solve(&until);
        finished.store(true, Ordering::Relaxed);
        watcher.thread().unpark();
        result
    })
}

impl<S: Dynamics + Continuous> Collocation<'_, S> {
    fn solve(&self, until: &Until) -> Result<Plan> {
        let mut rng = Rng::derive(self.req.seed, 0xD1_C0);
        let mut best: Option<(Run, usize)> = None;
        for start in 0..=self.req.restarts {
            self.planner.check()?;
            let z0 = self.initial_guess(start, &mut rng)?;
            let run = self.optimize(z0, until)?;
            if best.as_ref().is_none_or(|(b, _)| better(&run, b)) {
                best = Some((run, start));
            }
            if until.reached() {
                break;
            }
        }
        let (run, start) = best.expect("at least one start");
        let from_x_init = start == 0 && self.req.x_init.is_some();
        self.finish(run).map_err(|e| match e {
            // The caller's initial states, not x0, led the plan where the model fails.
            Error::Invalid { field, message } if field == "x0" && from_x_init => Error::invalid(
                "x_init",
                format!(
                    "{message} (collocation started from x_init: give initial states within \
                     the range the model was trained on, or leave x_init out to start from the \
                     rollout of u_init)"
                ),
            ),
            e => e,
        })
    }

    /// Start 0's inputs are `u_init` and its states `x_init`; a restart's inputs are drawn as
    /// iLQR draws them. States not given are the one-step map's rollout of the inputs, or,
    /// where that diverges, the straight line from x0 to the goal. Midpoints make every
    /// Hermite defect zero.
    fn initial_guess(&self, start: usize, rng: &mut Rng) -> Result<Vec<f64>> {
        let (l, req) = (&self.layout, self.req);
        let u = self.planner.initial_guess(start, rng);
        let mut x = match (&req.x_init, start) {
            (Some(x), 0) => x.data.clone(),
            _ => self.planner.rollout(u.clone())?.x,
        };
        if x.iter().any(|v| !v.is_finite()) {
            x = straight_line(&req.x0, &req.goal, req.horizon);
        }
        x[..l.nx].copy_from_slice(&req.x0);
        let mut z = vec![0.0; l.len()];
        for k in 0..=l.intervals {
            z[l.x(k)..][..l.nx].copy_from_slice(&x[k * l.nx..][..l.nx]);
        }
        for k in 0..l.intervals {
            z[l.u(k)..][..l.m].copy_from_slice(&u[k * l.m..][..l.m]);
        }
        // f at each interval's start and end under its input: x_c from the Hermite defect.
        let (mut xs, mut us) = (x[..l.intervals * l.nx].to_vec(), u.clone());
        xs.extend_from_slice(&x[l.nx..]);
        us.extend_from_slice(&u);
        let f = self.sys.derivative(&xs, &us);
        let t = l.intervals;
        for k in 0..t {
            for i in 0..l.nx {
                let (a, b) = (x[k * l.nx + i], x[(k + 1) * l.nx + i]);
                let slope = self.h / 8.0 * (f[k * l.nx + i] - f[(t + k) * l.nx + i]);
                let mid = 0.5 * (a + b) + slope;
                z[l.xc(k) + i] = if mid.is_finite() { mid } else { 0.5 * (a + b) };
            }
        }
        Ok(z)
    }

    /// J of the knots' states and inputs, as iLQR weighs them.
    fn cost(&self, z: &[f64]) -> f64 {
        let (x, u) = self.split(z);
        self.planner.cost(&x, &u)
    }

    /// The knot states `[T+1, nx]` and inputs `[T, m]` of `z`.
    fn split(&self, z: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let l = &self.layout;
        let x = (0..=l.intervals).flat_map(|k| z[l.x(k)..][..l.nx].iter().copied());
        let u = (0..l.intervals).flat_map(|k| z[l.u(k)..][..l.m].iter().copied());
        (x.collect(), u.collect())
    }

    /// The answer: iLQR's (gains from the one-step map along the plan, the goal's error), the
    /// largest defect, and how far the one-step map's rollout of the inputs strays from the
    /// collocated states (largest coordinate difference over the knots).
    fn finish(&self, run: Run) -> Result<Plan> {
        let (x, u) = self.split(&run.last.z);
        let t = Trajectory::new(x, u, run.last.cost);
        if !t.cost.is_finite() {
            return Err(self.planner.not_finite(&t));
        }
        let rollout = self.planner.rollout(t.u.clone())?.x;
        let deviation =
            (rollout.iter().zip(&t.x))
                .map(|(a, b)| (a - b).abs())
                .fold(
                    0.0f64,
                    |m, d| if d.is_nan() { f64::INFINITY } else { m.max(d) },
                );
        let mut plan = self.planner.finish(t, run.costs, run.converged)?;
        plan.method = Method::Dircol;
        plan.constraint_violation = run.last.violation;
        plan.rollout_deviation = deviation;
        Ok(plan)
    }
}

/// Feasible beats infeasible, then the lower cost among the feasible, the smaller violation
/// among the infeasible.
fn better(a: &Run, b: &Run) -> bool {
    let met = |r: &Run| r.last.violation <= DEFECT_TOLERANCE;
    match (met(a), met(b)) {
        (true, false) => true,
        (false, true) => false,
        (true, true) => a.last.cost < b.last.cost,
        (false, false) => a.last.violation < b.last.violation,
    }
}

/// `[T+1, nx]` states evenly from `from` to `to`.
pub fn straight_line(from: &[f64], to: &[f64], horizon: usize) -> Vec<f64> {
    (0..=horizon)
        .flat_map(|k| {
            let s = k as f64 / horizon as f64;
            from.iter().zip(to).map(move |(a, b)| a + s * (b - a))
        })
        .collect()
}

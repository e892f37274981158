//! The batched entry points over row-major arrays: what the service, the C library, the
//! Python module and the benchmarks call; a batch is cut in chunks that a caller's stop can
//! interrupt.

use super::limits::Pass;
use super::workspace::with_workspace;
use super::{Evaluator, continuous};
use crate::arena::{AVec, Arena};
use crate::control::linalg::Mat;
use crate::control::plan::Dynamics;

/// Batches at least this large run in two halves when the caller runs in a rayon pool: a
/// hand-off costs a few µs, a step of 64 states ~0.3 ms on one thread.
const PARALLEL_ROWS: usize = 32;

/// Batched entry points over row-major arrays: what the service and the benchmarks call.
impl Evaluator {
    /// The step of a call in seconds: the caller's `dt` when given (the dynamics are
    /// continuous, so a model trained at one rate answers at another), else the model's own.
    /// One range for every surface: the one a dataset's Δt must be in (`data::DT_RANGE`).
    pub fn step_seconds(&self, dt: Option<f64>) -> crate::error::Result<f64> {
        let Some(dt) = dt else {
            return Ok(self.config.dt);
        };
        let (lo, hi) = crate::data::DT_RANGE;
        if dt.is_finite() && (lo..=hi).contains(&dt) {
            return Ok(dt);
        }
        Err(crate::error::Error::invalid(
            "dt",
            format!(
                "must be a number of seconds in [{lo:e}, {hi}] (unset: the model's own, {}), got {dt}",
                self.config.dt
            ),
        ))
    }

    /// x' (and v̇ when asked) for `[B, nq + nv]` states and `[B, m]` inputs.
    pub fn predict(&self, x: &[f64], u: &[f64], want_accel: bool) -> (Vec<f64>, Option<Vec<f64>>) {
        self.predict_until(x, u, self.config.dt, want_accel, &|| false)
            .expect("never stopped")
    }

    /// [`Evaluator::predict`] with steps of `dt` seconds (`config.dt`: the model's own), or
    /// `None` when `stop` says so before a chunk.
    pub fn predict_until(
        &self,
        x: &[f64],
        u: &[f64],
        dt: f64,
        want_accel: bool,
        stop: &dyn Fn() -> bool,
    ) -> Option<(Vec<f64>, Option<Vec<f64>>)> {
        let (nx, nv) = (self.config.nx(), self.config.nv());
        let mut next = vec![0.0; x.len()];
        let mut acc = vec![0.0; if want_accel { x.len() / nx * nv } else { 0 }];
        let outs = (
            (&mut next[..], nx),
            (&mut acc[..], if want_accel { nv } else { 0 }),
        );
        self.in_halves(x, u, Pass::Step, stop, outs, |x, u, next, acc| {
            let acc = want_accel.then_some(acc);
            with_workspace(|ws| self.predict_into(ws, x, u, dt, next, acc, &|| false));
        })?;
        Some((next, want_accel.then_some(acc)))
    }

    /// A `[B, 2nv, 2nv]` and B `[B, 2nv, m]` for a batch, in the tangent space
    /// (x' ⊖ x̄' = A (x ⊖ x̄) + B (u − ū)): the state's deviations and the input are dual
    /// variables (2nv + m directions, each sample its own), pushed through one step.
    pub fn linearize_batch(&self, x: &[f64], u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        self.linearize_until(x, u, &|| false)
            .expect("never stopped")
    }

    /// [`Evaluator::linearize_batch`], or `None` when `stop` says so before a chunk.
    pub fn linearize_until(
        &self,
        x: &[f64],
        u: &[f64],
        stop: &dyn Fn() -> bool,
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let (nx, ndx, m) = (self.config.nx(), self.config.ndx(), self.config.m);
        let rows = x.len() / nx;
        let mut a = vec![0.0; rows * ndx * ndx];
        let mut b = vec![0.0; rows * ndx * m];
        let outs = ((&mut a[..], ndx * ndx), (&mut b[..], ndx * m));
        self.in_halves(x, u, Pass::Linearize, stop, outs, |x, u, a, b| {
            with_workspace(|ws| self.linearize_into(ws, x, u, a, b, &|| false));
        })?;
        Some((a, b))
    }

    /// Each of a unit's states' rows [∂x'_i/∂δx, ∂x'_i/∂u] (in the tangent space), in the
    /// arena: by the multibody algorithms' derivatives state by state where they apply, else
    /// dual numbers through the unit's step.
    pub(super) fn jacobian_rows<'a>(&'a self, a: &'a Arena, x: &[f64], u: &[f64]) -> AVec<'a, f64> {
        let (nx, m) = (self.config.nx(), self.config.m);
        let Some(robot) = self.jacobian_robot() else {
            let space = (&self.config.space, continuous::Output::State);
            return continuous::dual_rows_in(a, space, m, x, u, |x, u| {
                self.step_in(a, x, u, self.config.dt)
            });
        };
        let mut rows = AVec::with_capacity_in(x.len() * (nx + m), a);
        // By index, not `u.chunks(m)`: a robot without inputs has empty rows of u.
        for b in 0..x.len() / nx {
            let (x, u) = (&x[nx * b..][..nx], &u[m * b..][..m]);
            rows.extend_from_slice(&self.multibody_jacobian(a, robot, x, u));
        }
        rows
    }

    /// Runs `f` over a batch in chunks whose intermediate work is bounded (see [`limits`]) on
    /// the caller's thread, or, when the caller runs in a rayon pool of its own (its way of
    /// asking for threads), each chunk in two halves on that pool when it is large enough to
    /// pay off (the pool's threads live on, each with its workspace; no thread is started),
    /// each part writing its rows of the two outputs (`width` values a row); `None` when
    /// `stop` says so before a chunk (a 10⁶-state batch takes seconds: a caller's deadline
    /// must not wait for all of it).
    #[allow(clippy::type_complexity)]
    fn in_halves(
        &self,
        x: &[f64],
        u: &[f64],
        pass: Pass,
        stop: &dyn Fn() -> bool,
        ((first, w1), (second, w2)): ((&mut [f64], usize), (&mut [f64], usize)),
        f: impl Fn(&[f64], &[f64], &mut [f64], &mut [f64]) + Sync,
    ) -> Option<()> {
        let (nx, m) = (self.config.nx(), self.config.m);
        let (rows, chunk) = (x.len() / nx, 2 * self.chunk_states(pass));
        for s in (0..rows).step_by(chunk) {
            if stop() {
                return None;
            }
            let e = rows.min(s + chunk);
            let (x, u) = (&x[nx * s..nx * e], &u[m * s..m * e]);
            let (o1, o2) = (&mut first[w1 * s..w1 * e], &mut second[w2 * s..w2 * e]);
            if e - s < PARALLEL_ROWS || rayon::current_thread_index().is_none() {
                f(x, u, o1, o2);
                continue;
            }
            let h = (e - s) / 2;
            let ((x0, x1), (u0, u1)) = (x.split_at(nx * h), u.split_at(m * h));
            let ((a0, a1), (b0, b1)) = (o1.split_at_mut(w1 * h), o2.split_at_mut(w2 * h));
            rayon::join(|| f(x0, u0, a0, b0), || f(x1, u1, a1, b1));
        }
        Some(())
    }

    /// `steps` states after x0, `dt` seconds apart, under inputs `u_t = input(t, x_t)`, each
    /// handed to `emit` (state, input) as computed; `emit` returning false stops the rollout
    /// early.
    pub fn rollout(
        &self,
        x0: &[f64],
        (steps, dt): (usize, f64),
        input: impl Fn(usize, &[f64]) -> Vec<f64>,
        mut emit: impl FnMut(&[f64], &[f64]) -> bool,
    ) {
        let (mut x, mut next) = (x0.to_vec(), vec![0.0; x0.len()]);
        for t in 0..steps {
            let u = input(t, &x);
            with_workspace(|ws| self.predict_into(ws, &x, &u, dt, &mut next, None, &|| false));
            std::mem::swap(&mut x, &mut next);
            if !emit(&x, &u) {
                return;
            }
        }
    }
}

/// Plans run on the model's one-step map and its exact Jacobians (`control::plan`).
impl Dynamics for Evaluator {
    fn nx(&self) -> usize {
        self.config.nx()
    }
    fn m(&self) -> usize {
        self.config.m
    }
    fn step(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        self.predict(x, u, false).0
    }
    fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        let (a, b) = self.linearize_batch(x, u);
        self.jacobians(a, b)
    }
    fn ndx(&self) -> usize {
        self.config.ndx()
    }
    fn difference(&self, x0: &[f64], x1: &[f64]) -> Vec<f64> {
        self.config.space.state_difference(x0, x1)
    }
    fn chart_of(&self, x: &[f64]) -> Vec<f64> {
        self.config.space.state_chart(x)
    }
    fn state_at(&self, c: &[f64]) -> Vec<f64> {
        self.config.space.state_from_chart(c)
    }
}

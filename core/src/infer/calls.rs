//! The batched entry points over row-major arrays: what the service, the C library, the
//! Python module and the benchmarks call; a batch is cut in chunks that a caller's stop can
//! interrupt.

use super::col::{Col, Column};
use super::limits::Pass;
use super::{Evaluator, columns, continuous, ensemble, to_rows};
use crate::control::linalg::Mat;
use crate::control::plan::Dynamics;

/// Batches at least this large run on two threads: a thread costs ~20–40 µs, a step of 64
/// states ~0.35 ms on one (measured: 64 states in 0.26 ms split vs 0.35–0.48 ms not).
const PARALLEL_ROWS: usize = 32;

/// Batched entry points over row-major arrays: what the service and the benchmarks call.
impl Evaluator {
    /// x' (and q̈ when asked) for `[B, 2n]` states and `[B, m]` inputs.
    pub fn predict(&self, x: &[f64], u: &[f64], want_accel: bool) -> (Vec<f64>, Option<Vec<f64>>) {
        self.predict_until(x, u, want_accel, &|| false)
            .expect("never stopped")
    }

    /// [`Evaluator::predict`], or `None` when `stop` says so before a chunk.
    pub fn predict_until(
        &self,
        x: &[f64],
        u: &[f64],
        want_accel: bool,
        stop: &dyn Fn() -> bool,
    ) -> Option<(Vec<f64>, Option<Vec<f64>>)> {
        if let Some(members) = &self.members {
            return ensemble::mean_prediction(members, x, u, want_accel, stop);
        }
        let parts = self.split(x, u, Pass::Step, stop, |x, u| {
            if self.multibody.is_some() {
                self.predict_each(x, u, want_accel)
            } else if x.len() == 2 * self.config.n {
                self.predict_cols::<f64>(x, u, want_accel)
            } else {
                self.predict_cols::<Col>(x, u, want_accel)
            }
        })?;
        let mut next = vec![];
        let mut acc = want_accel.then(Vec::new);
        for (x, a) in parts {
            next.extend(x);
            acc.iter_mut().zip(a).for_each(|(acc, a)| acc.extend(a));
        }
        Some((next, acc))
    }

    pub(super) fn predict_cols<C: Column>(
        &self,
        x: &[f64],
        u: &[f64],
        want_accel: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let n = self.config.n;
        let (x, u) = (columns::<C>(x, 2 * n), columns::<C>(u, self.config.m));
        let next = to_rows(&self.step(&x, &u));
        let acc = want_accel.then(|| to_rows(&self.accel(&x[..n], &x[n..], &u)));
        (next, acc)
    }

    /// A `[B, 2n, 2n]` and B `[B, 2n, m]` for a batch: the state's and input's coordinates
    /// are dual variables (2n + m directions, each sample its own), pushed through one step.
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
        if let Some(members) = &self.members {
            return ensemble::mean_linearization(members, x, u, stop);
        }
        let (nx, m) = (2 * self.config.n, self.config.m);
        let parts = self.split(x, u, Pass::Linearize, stop, |x, u| {
            let multibody = (self.multibody.as_ref()).and_then(|model| {
                let rows = x.chunks(nx).zip(u.chunks(m));
                rows.map(|(x, u)| self.multibody_jacobian(model, x, u))
                    .collect::<Option<Vec<_>>>()
            });
            if let Some(rows) = multibody {
                rows.concat()
            } else if x.len() == nx {
                self.jacobian_rows(columns::<f64>(x, nx), columns(u, m))
            } else {
                self.jacobian_rows(columns::<Col>(x, nx), columns(u, m))
            }
        })?;
        let (mut a, mut b) = (Vec::with_capacity(x.len() * nx), Vec::new());
        for row in parts.concat().chunks(nx + m) {
            a.extend(&row[..nx]);
            b.extend(&row[nx..]);
        }
        Some((a, b))
    }

    /// Per sample, per output coordinate, the row [∂x'_i/∂x, ∂x'_i/∂u].
    fn jacobian_rows<C: Column>(&self, x: Vec<C>, u: Vec<C>) -> Vec<f64> {
        continuous::dual_rows(x, u, |x, u| self.step(x, u))
    }

    /// Runs `f` over a batch in chunks whose intermediate work is bounded (see [`limits`]),
    /// each in two halves on two threads when it is large enough for the thread to pay off;
    /// the parts in order, or `None` when `stop` says so before a chunk (a 10⁶-state batch
    /// takes seconds: a caller's deadline must not wait for all of it).
    pub(super) fn split<T: Send>(
        &self,
        x: &[f64],
        u: &[f64],
        pass: Pass,
        stop: &dyn Fn() -> bool,
        f: impl Fn(&[f64], &[f64]) -> T + Sync,
    ) -> Option<Vec<T>> {
        let (nx, m) = (2 * self.config.n, self.config.m);
        let chunk = 2 * self.chunk_states(pass);
        let mut parts = Vec::new();
        for (x, u) in x.chunks(chunk * nx).zip(u.chunks(chunk * m)) {
            if stop() {
                return None;
            }
            let rows = x.len() / nx;
            if rows < PARALLEL_ROWS {
                parts.push(f(x, u));
                continue;
            }
            let half = rows / 2;
            let (x0, x1) = x.split_at(half * nx);
            let (u0, u1) = u.split_at(half * m);
            std::thread::scope(|s| {
                let second = s.spawn(|| f(x1, u1));
                parts.push(f(x0, u0));
                parts.push(second.join().expect("inference thread"));
            });
        }
        Some(parts)
    }

    /// `steps` states after x0 under inputs `u_t = input(t, x_t)`, each handed to `emit`
    /// (state, input) as computed; `emit` returning false stops the rollout early.
    pub fn rollout(
        &self,
        x0: &[f64],
        steps: usize,
        input: impl Fn(usize, &[f64]) -> Vec<f64>,
        mut emit: impl FnMut(&[f64], &[f64]) -> bool,
    ) {
        let mut x = x0.to_vec();
        for t in 0..steps {
            let u = input(t, &x);
            x = self.mean_step(&x[..], &u);
            if !emit(&x, &u) {
                return;
            }
        }
    }
}

/// Plans run on the model's one-step map and its exact Jacobians (`control::plan`).
impl Dynamics for Evaluator {
    fn nx(&self) -> usize {
        2 * self.config.n
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
}

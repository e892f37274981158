//! The model's continuous dynamics ẋ = f(x, u) = (q̇, q̈(q, q̇, u)) and its exact Jacobians,
//! for direct collocation (`control::dircol`), which constrains knot states by f rather than
//! by the integrator's one-step map. The Jacobians are dual numbers pushed through q̈ alone,
//! as Linearize pushes them through a whole step.

use std::ops::Deref;

use super::Evaluator;
use super::ensemble::mean;
use super::limits::Pass;
use super::workspace::with_workspace;
use crate::arena::{AVec, Arena};
use crate::control::dircol::Continuous;
use crate::control::linalg::Mat;
use crate::physics::dual::{Dual, Jet, WIDTH, groups_of};

/// A dual number over one state's directions (x's then u's), a group of eight at a time.
pub(super) type Outer = Jet<WIDTH>;

impl Evaluator {
    /// f = (q̇, q̈) at each row of `[B, 2n]` states and `[B, m]` inputs, in an arena.
    fn derivative_in<'a, S: super::Lanes>(&'a self, a: &'a Arena, x: &[S], u: &[S]) -> AVec<'a, S> {
        let n = self.config.n;
        let qdd = self.evaluate_in(a, self.rows(x, u), false);
        let mut f = AVec::with_capacity_in(x.len(), a);
        for (x, qdd) in x.chunks(2 * n).zip(qdd.chunks(n)) {
            f.extend(x[n..].iter().chain(qdd).cloned());
        }
        f
    }
}

/// The Jacobians of `f` at each of a batch's states (`[B, nx]` and `[B, m]`): each state's
/// coordinates of (x, u) are dual variables of its own, a group of directions at a time
/// (`dual::groups_of`, the same group in every state), so that the networks run once over the
/// batch (matrix products) rather than once per state. Per state and output, in order, the
/// row [∂f_i/∂x, ∂f_i/∂u].
pub(super) fn dual_rows_in<'a, Y: Deref<Target = [Outer]>>(
    a: &'a Arena,
    (nx, m): (usize, usize),
    x: &[f64],
    u: &[f64],
    f: impl Fn(&[Outer], &[Outer]) -> Y,
) -> AVec<'a, f64> {
    let (states, dirs) = (x.len() / nx, nx + m);
    let mut out = AVec::new_in(a);
    if states == 0 {
        return out;
    }
    for group in groups_of(dirs, WIDTH) {
        let mut xs = AVec::with_capacity_in(x.len(), a);
        let mut us = AVec::with_capacity_in(u.len(), a);
        for b in 0..states {
            let xu = x[nx * b..][..nx].iter().chain(&u[m * b..][..m]);
            for (k, &v) in xu.enumerate() {
                let d = match group.contains(&k) {
                    true => Dual::variable(v, k - group.start, group.len(), 1.0),
                    false => Dual::constant(v),
                };
                if k < nx { xs.push(d) } else { us.push(d) }
            }
        }
        let y = f(&xs, &us);
        if out.is_empty() {
            out.resize(y.len() * dirs, 0.0);
        }
        for (row, yi) in out.chunks_exact_mut(dirs).zip(y.iter()) {
            for (k, o) in row[group.clone()].iter_mut().enumerate() {
                *o = yi.tangent(k).copied().unwrap_or(0.0);
            }
        }
    }
    out
}

impl Continuous for Evaluator {
    fn nx(&self) -> usize {
        2 * self.config.n
    }
    fn m(&self) -> usize {
        self.config.m
    }
    fn dt(&self) -> f64 {
        self.config.dt
    }
    fn derivative(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        if let Some(members) = self.ensemble() {
            return mean(members.iter().map(|e| e.derivative(x, u)));
        }
        let (nx, m) = (2 * self.config.n, self.config.m);
        let mut out = Vec::with_capacity(x.len());
        with_workspace(|ws| {
            for r in self.units(x.len() / nx, Pass::Step) {
                let (x, u) = (&x[nx * r.start..nx * r.end], &u[m * r.start..m * r.end]);
                out.extend(self.derivative_in(ws.reset().0, x, u));
            }
        });
        out
    }
    fn derivative_jacobian(&self, x: &[f64], u: &[f64]) -> (Vec<Mat>, Vec<Mat>) {
        if let Some(members) = self.ensemble() {
            let each: Vec<_> = members
                .iter()
                .map(|e| e.derivative_jacobian(x, u))
                .collect();
            let flat = |m: &[Mat]| m.iter().flat_map(|m| m.data.clone()).collect::<Vec<f64>>();
            let a = mean(each.iter().map(|(a, _)| flat(a)));
            let b = mean(each.iter().map(|(_, b)| flat(b)));
            return self.jacobians(a, b);
        }
        let (nx, m) = (2 * self.config.n, self.config.m);
        let (mut ja, mut jb) = (Vec::with_capacity(x.len() * nx), Vec::new());
        with_workspace(|ws| {
            for r in self.units(x.len() / nx, Pass::Linearize) {
                let (x, u) = (&x[nx * r.start..nx * r.end], &u[m * r.start..m * r.end]);
                let a = ws.reset().0;
                let rows = dual_rows_in(a, (nx, m), x, u, |x, u| self.derivative_in(a, x, u));
                for row in rows.chunks(nx + m) {
                    ja.extend(&row[..nx]);
                    jb.extend(&row[nx..]);
                }
            }
        });
        self.jacobians(ja, jb)
    }
}

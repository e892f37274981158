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
use crate::physics::space::Space;

/// A dual number over one state's directions (x's then u's), a group of eight at a time.
pub(super) type Outer = Jet<WIDTH>;

impl Evaluator {
    /// f = (v, v̇) (a tangent, 2nv wide) at each row of `[B, nq + nv]` states and `[B, m]`
    /// inputs, in an arena.
    fn derivative_in<'a, S: super::Lanes>(&'a self, a: &'a Arena, x: &[S], u: &[S]) -> AVec<'a, S> {
        let (nq, nv) = (self.config.nq(), self.config.nv());
        let vdot = self.evaluate_in(a, self.rows(x, u), false);
        let mut f = AVec::with_capacity_in(2 * vdot.len(), a);
        for (x, vdot) in x.chunks(nq + nv).zip(vdot.chunks(nv)) {
            f.extend(x[nq..].iter().chain(vdot).cloned());
        }
        f
    }
}

/// What a function of states answers: states [q, v] (a step), or tangents (f = (v, v̇)).
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Output {
    State,
    Tangent,
}

/// The Jacobians of `f` at each of a batch's states (`[B, nq + nv]` and `[B, m]`) in the
/// tangent space (docs/dynamics.md#configuration-space): each state's deviations δx = [δq, δv]
/// (x = x̄ ⊕ δx) and u are dual variables of its own, a group of directions at a time
/// (`dual::groups_of`, the same group in every state), so that the networks run once over the
/// batch (matrix products) rather than once per state; an output state's configuration is
/// read back through `difference` (x' ⊖ x̄'). Per state and output tangent coordinate, in
/// order, the row [∂f_i/∂δx, ∂f_i/∂u].
pub(super) fn dual_rows_in<'a, Y: Deref<Target = [Outer]>>(
    a: &'a Arena,
    (space, output): (&Space, Output),
    m: usize,
    x: &[f64],
    u: &[f64],
    f: impl Fn(&[Outer], &[Outer]) -> Y,
) -> AVec<'a, f64> {
    let (nq, nv) = (space.nq(), space.nv());
    let (nx, dirs) = (nq + nv, 2 * nv + m);
    let states = x.len() / nx;
    let mut out = AVec::new_in(a);
    if states == 0 {
        return out;
    }
    // The outputs' rows over the state's own coordinates, then (for a space that is not
    // flat) mapped to its tangent.
    let mut raw = AVec::new_in(a);
    let mut primal = AVec::new_in(a);
    for group in groups_of(dirs, WIDTH) {
        let mut xs = AVec::with_capacity_in(x.len(), a);
        let mut us = AVec::with_capacity_in(u.len(), a);
        let var = |v: f64, k: usize| match group.contains(&k) {
            true => Dual::variable(v, k - group.start, group.len(), 1.0),
            false => Dual::constant(v),
        };
        for b in 0..states {
            let (q, v) = x[nx * b..][..nx].split_at(nq);
            if space.is_flat() {
                xs.extend(q.iter().enumerate().map(|(k, &q)| var(q, k)));
            } else {
                xs.extend(space.seeded_in(a, q, &1.0, group.clone()).iter().cloned());
            }
            xs.extend(v.iter().enumerate().map(|(k, &v)| var(v, nv + k)));
            us.extend((u[m * b..][..m].iter().enumerate()).map(|(k, &u)| var(u, 2 * nv + k)));
        }
        let y = f(&xs, &us);
        if raw.is_empty() {
            raw.resize(y.len() * dirs, 0.0);
            primal.extend(y.iter().map(|y| y.v));
        }
        for (row, yi) in raw.chunks_exact_mut(dirs).zip(y.iter()) {
            for (k, o) in row[group.clone()].iter_mut().enumerate() {
                *o = yi.tangent(k).copied().unwrap_or(0.0);
            }
        }
    }
    if space.is_flat() || output == Output::Tangent {
        return raw;
    }
    out.reserve(states * 2 * nv * dirs);
    for (rows, y) in raw.chunks(nx * dirs).zip(primal.chunks(nx)) {
        space.tangent_rows(&y[..nq], &rows[..nq * dirs], dirs, &mut out);
        out.extend_from_slice(&rows[nq * dirs..]);
    }
    out
}

impl Continuous for Evaluator {
    fn nx(&self) -> usize {
        self.config.ndx()
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
        let (nx, m) = (self.config.nx(), self.config.m);
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
        let (nx, ndx, m) = (self.config.nx(), self.config.ndx(), self.config.m);
        let (mut ja, mut jb) = (Vec::with_capacity(x.len() * ndx), Vec::new());
        with_workspace(|ws| {
            for r in self.units(x.len() / nx, Pass::Linearize) {
                let (x, u) = (&x[nx * r.start..nx * r.end], &u[m * r.start..m * r.end]);
                let a = ws.reset().0;
                let space = (&self.config.space, Output::Tangent);
                let rows = dual_rows_in(a, space, m, x, u, |x, u| self.derivative_in(a, x, u));
                for row in rows.chunks(ndx + m) {
                    ja.extend(&row[..ndx]);
                    jb.extend(&row[ndx..]);
                }
            }
        });
        self.jacobians(ja, jb)
    }
}

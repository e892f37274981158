//! The model's continuous dynamics ẋ = f(x, u) = (q̇, q̈(q, q̇, u)) and its exact Jacobians,
//! for direct collocation (`control::dircol`), which constrains knot states by f rather than
//! by the integrator's one-step map. The Jacobians are dual numbers pushed through q̈ alone,
//! as Linearize pushes them through a whole step.

use super::Evaluator;
use super::col::{Col, Column};
use super::ensemble::mean;
use super::limits::Pass;
use super::{columns, to_rows};
use crate::control::dircol::Continuous;
use crate::control::linalg::Mat;
use crate::physics::dual::{Dual, Tangents, groups_of};

impl Evaluator {
    /// f at each row of `[B, 2n]` states and `[B, m]` inputs: q̇, then q̈.
    fn derivative_rows<C: Column>(&self, x: &[f64], u: &[f64]) -> Vec<f64> {
        let (n, m) = (self.config.n, self.config.m);
        let xc: Vec<C> = columns(x, 2 * n);
        let uc: Vec<C> = columns(u, m);
        let acc = self.accel(&xc[..n], &xc[n..], &uc);
        let mut cols = xc[n..].to_vec();
        cols.extend(acc);
        to_rows(&cols)
    }

    /// Per row, per output coordinate of f, the row [∂f_i/∂x, ∂f_i/∂u].
    fn derivative_jacobian_rows<C: Column>(&self, x: Vec<C>, u: Vec<C>) -> Vec<f64> {
        let n = self.config.n;
        dual_rows(x, u, |x, u| {
            let mut f = x[n..].to_vec();
            f.extend(self.accel(&x[..n], &x[n..], u));
            f
        })
    }
}

/// `f`'s Jacobian at each row of the columns `x` and `u`: every coordinate a dual variable
/// (x's then u's directions), a group of directions at a time (`dual::groups`); per row, per
/// output, the row [∂f_i/∂x, ∂f_i/∂u].
pub(super) fn dual_rows<C: Column>(
    x: Vec<C>,
    u: Vec<C>,
    f: impl Fn(&[Dual<C, C::Tangents>], &[Dual<C, C::Tangents>]) -> Vec<Dual<C, C::Tangents>>,
) -> Vec<f64> {
    let (nx, rows) = (x.len(), x[0].rows());
    let xu: Vec<C> = x.into_iter().chain(u).collect();
    let (dirs, one) = (xu.len(), xu[0].lift(1.0));
    let mut out: Vec<f64> = vec![];
    for group in groups_of(dirs, C::Tangents::WIDTH) {
        let seeded = Dual::seeded(&xu, &one, group.clone());
        let y = f(&seeded[..nx], &seeded[nx..]);
        if out.is_empty() {
            out = vec![0.0; rows * y.len() * dirs];
        }
        for b in 0..rows {
            for (i, yi) in y.iter().enumerate() {
                let at = (b * y.len() + i) * dirs + group.start;
                for k in 0..group.len() {
                    out[at + k] = yi.tangent(k).map_or(0.0, |t| t.get(b));
                }
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
        let parts = self.split(x, u, Pass::Step, &|| false, |x, u| {
            self.derivative_rows::<Col>(x, u)
        });
        parts.expect("never stopped").concat()
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
        let parts = self.split(x, u, Pass::Linearize, &|| false, |x, u| {
            self.derivative_jacobian_rows(columns::<Col>(x, nx), columns(u, m))
        });
        let (mut a, mut b) = (Vec::with_capacity(x.len() * nx), Vec::new());
        for row in parts.expect("never stopped").concat().chunks(nx + m) {
            a.extend(&row[..nx]);
            b.extend(&row[nx..]);
        }
        self.jacobians(a, b)
    }
}

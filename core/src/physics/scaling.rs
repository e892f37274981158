//! Input and output scalings from dataset statistics, stored with the model.
//!
//! With u ~ N(0, 120²) the generalized forces are O(100): unscaled networks barely train
//! (docs/training.md#input-and-output-scalings). Network inputs are standardized, and network outputs are multiplied by the
//! scale their physical quantity has in the data. M's scale is free (identifiability), so a
//! learned M starts near the identity and forces are scaled like accelerations; with an analytic
//! M the force scale is the spread of M(q)q̈ over the data at the initial parameters.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::dual::Dual;
use super::scalar::Scalar;
use super::space::{Joint, Space};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scaling {
    pub q_mean: Vec<f64>,
    pub q_std: Vec<f64>,
    pub qdot_mean: Vec<f64>,
    pub qdot_std: Vec<f64>,
    pub u_mean: Vec<f64>,
    pub u_std: Vec<f64>,
    /// Statistics of the finite-difference accelerations (q̇' − q̇)/Δt.
    pub acc_mean: Vec<f64>,
    pub acc_std: Vec<f64>,
    /// Typical size of each generalized force.
    pub force_scale: Vec<f64>,
}

impl Scaling {
    /// Every statistic is a finite number.
    pub fn is_finite(&self) -> bool {
        [
            &self.q_mean,
            &self.q_std,
            &self.qdot_mean,
            &self.qdot_std,
            &self.u_mean,
            &self.u_std,
            &self.acc_mean,
            &self.acc_std,
            &self.force_scale,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
    }

    /// Identity scalings (used where no data is at hand, e.g. in unit tests) for nq
    /// configuration values, n velocities and m inputs.
    pub fn identity(nq: usize, n: usize, m: usize) -> Self {
        Self {
            q_mean: vec![0.0; nq],
            q_std: vec![1.0; nq],
            qdot_mean: vec![0.0; n],
            qdot_std: vec![1.0; n],
            u_mean: vec![0.0; m],
            u_std: vec![1.0; m],
            acc_mean: vec![0.0; n],
            acc_std: vec![1.0; n],
            force_scale: vec![1.0; n],
        }
    }

    pub fn mean_force_scale(&self) -> f64 {
        self.force_scale.iter().sum::<f64>() / self.force_scale.len() as f64
    }

    pub fn mean_q_std(&self) -> f64 {
        self.q_std.iter().sum::<f64>() / self.q_std.len() as f64
    }

    /// Scale of a learned quadratic potential's K: K q is O(force) when q is O(σ_q).
    pub fn quadratic_scale(&self) -> f64 {
        self.mean_force_scale() / self.mean_q_std()
    }

    /// Output scale of a potential network: ∂V/∂q should be O(force) when q moves by O(σ_q).
    pub fn potential_scale(&self) -> f64 {
        self.mean_force_scale() * self.mean_q_std()
    }
}

/// The networks' inputs as values of any number type (the training tape's; the f64
/// evaluator builds the same inputs in its batched form).
impl Scaling {
    /// The input from q: standardized, an angle as (sin q_k, cos q_k), a rotation as its
    /// (cos θ, sin θ) itself; each input carries its ∂/∂q in the tangent directions `dirs`
    /// (none for an empty range).
    pub fn q_features<S: Scalar>(
        &self,
        q: &[S],
        space: &Space,
        dirs: Range<usize>,
    ) -> Vec<Dual<S>> {
        let mut out = vec![];
        self.q_features_into(q, space, dirs, &mut out);
        out
    }

    /// [`Scaling::q_features`] appended to `out` (an arena's vector on the inference path).
    pub fn q_features_into<S: Scalar>(
        &self,
        q: &[S],
        space: &Space,
        dirs: Range<usize>,
        out: &mut impl Extend<Dual<S>>,
    ) {
        for p in space.placed() {
            let with = |v: S, d: S| -> Dual<S> {
                if !dirs.contains(&p.v) {
                    return Dual::constant(v);
                }
                Dual::variable(v, p.v - dirs.start, dirs.len(), d)
            };
            let k = p.q.start;
            let qk = &q[k];
            match p.joint {
                Joint::Angle => {
                    let (sin, cos) = (qk.sin(), qk.cos());
                    out.extend([with(sin.clone(), cos.clone()), with(cos, -sin)]);
                }
                Joint::Circle => {
                    let (c, s) = (qk.clone(), q[k + 1].clone());
                    out.extend([with(c.clone(), -s.clone()), with(s, c)]);
                }
                Joint::Real => {
                    let inv = 1.0 / self.q_std[k];
                    out.extend([with(qk.shift(-self.q_mean[k]).scale(inv), qk.lift(inv))]);
                }
            }
        }
    }

    /// The input from [q, q̇, u]: q's as [`Scaling::q_features`] gives it, then q̇ and u
    /// standardized.
    pub fn full_features<S: Scalar>(&self, q: &[S], qd: &[S], u: &[S], space: &Space) -> Vec<S> {
        let mut out: Vec<S> = (self.q_features(q, space, 0..0).into_iter())
            .map(|d| d.v)
            .collect();
        let standardized = |x: &[S], mean: &[f64], std: &[f64]| -> Vec<S> {
            (x.iter().zip(mean.iter().zip(std)))
                .map(|(x, (m, s))| x.shift(-m).scale(1.0 / s))
                .collect()
        };
        out.extend(standardized(qd, &self.qdot_mean, &self.qdot_std));
        out.extend(standardized(u, &self.u_mean, &self.u_std));
        out
    }
}

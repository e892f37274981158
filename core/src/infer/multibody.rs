//! URDF models on the multibody algorithms (docs/robots.md#multibody-dynamics):
//! when M is a URDF template's, q̈ = FD(q, q̇, τ) by the articulated-body algorithm (CRBA and
//! a Cholesky solve with mimic joints) at the model's physical values, with τ = F − ∂V′/∂q
//! from the assembly (forces, residual networks, a potential that is not the template's).
//! O(n) per state where the template's M(q) and V(q) over dual numbers grow steeply with n.
//!
//! A step's Jacobian runs the integrator on dense dual numbers (`Jet`) over (x, u) (all its
//! directions at once, so each stage's partials are computed once) and takes each stage's
//! q̈ with its derivatives by the implicit function theorem (Carpentier & Mansard, RSS 2018):
//! ID(q, q̇, q̈) = τ(q, q̇, u) gives ∂q̈/∂z = M⁻¹ (∂τ/∂z − ∂ID/∂z) at q̈ = FD(q, q̇, τ), with
//! ∂ID/∂(q, q̇) from RNEA's analytic derivatives and ∂τ/∂z from the assembly over dual numbers.

use super::Evaluator;
use super::weights::Weights;
use crate::model::ModelConfig;
use crate::physics::dual::{Dual, Jet};
use crate::physics::multibody::{Model as Robot, with_data};
use crate::physics::templates::Template;

/// The robot as the multibody algorithms take it, for a structured model whose M is a URDF
/// template's; gravity is in it when V is the template's too.
pub(super) fn model_of(config: &ModelConfig, weights: &Weights) -> Option<Robot> {
    let (t, gravity) = config.spec.multibody()?;
    let Weights::Structured(w) = weights else {
        return None;
    };
    Some(t.multibody_model(w.physical.as_deref()?, gravity))
}

impl Evaluator {
    /// The same model evaluated by the template's M(q) and V(q) assembly instead of the
    /// multibody algorithms: the reference they are tested against, and the figure a
    /// benchmark compares them with.
    pub fn assembled(mut self) -> Self {
        self.multibody = None;
        if let Some(members) = &self.members {
            let assembled = members.iter().map(|m| m.clone().assembled());
            self.members = Some(assembled.collect::<Vec<_>>().into());
        }
        self
    }

    /// Each input's most force or torque where the model says (a URDF's `<limit effort>`).
    pub fn effort_limits(&self) -> Vec<Option<f64>> {
        match self.config.template() {
            Some(Template::Urdf(t)) => t.effort_limits(),
            _ => vec![None; self.config.m],
        }
    }

    /// Whether q̈ comes from the multibody algorithms.
    pub fn is_multibody(&self) -> bool {
        self.multibody.is_some()
    }

    /// `predict_cols` state by state in f64: O(n) work each, where batch columns would
    /// allocate a column for every operation of the recursion (64 UR5 states: 0.9 ms as
    /// columns).
    pub(super) fn predict_each(
        &self,
        x: &[f64],
        u: &[f64],
        want_accel: bool,
    ) -> (Vec<f64>, Option<Vec<f64>>) {
        let (nx, m) = (2 * self.config.n, self.config.m);
        let mut next = Vec::with_capacity(x.len());
        let mut acc = want_accel.then(|| Vec::with_capacity(x.len() / 2));
        for (x, u) in x.chunks(nx).zip(u.chunks(m)) {
            let (x, a) = self.predict_cols::<f64>(x, u, want_accel);
            next.extend(x);
            acc.iter_mut().zip(a).for_each(|(acc, a)| acc.extend(a));
        }
        (next, acc)
    }

    /// Per output coordinate of one state's step, the row [∂x'_i/∂x, ∂x'_i/∂u] (as
    /// `jacobian_rows`); `None` beyond 64 directions (then dual numbers do it).
    pub(super) fn multibody_jacobian(
        &self,
        model: &Robot,
        x: &[f64],
        u: &[f64],
    ) -> Option<Vec<f64>> {
        Some(match x.len() + u.len() {
            0..=8 => self.step_jacobian::<8>(model, x, u),
            9..=16 => self.step_jacobian::<16>(model, x, u),
            17..=32 => self.step_jacobian::<32>(model, x, u),
            33..=64 => self.step_jacobian::<64>(model, x, u),
            _ => return None,
        })
    }

    fn step_jacobian<const N: usize>(&self, model: &Robot, x: &[f64], u: &[f64]) -> Vec<f64> {
        let (n, nx, dirs) = (self.config.n, x.len(), x.len() + u.len());
        let xu: Vec<Jet<N>> = Dual::seeded(&[x, u].concat(), &1.0, 0..dirs);
        let (xj, uj) = xu.split_at(nx);
        let y = self
            .config
            .integrator
            .step(&xj.to_vec(), self.config.dt, |x: &Vec<Jet<N>>| {
                let (q, qd) = x.split_at(n);
                let mut dx = qd.to_vec();
                dx.extend(self.stage(model, q, qd, uj));
                dx
            });
        y.iter().flat_map(|y| y.dense()[..dirs].to_vec()).collect()
    }

    /// q̈ at one stage of the integrator, its tangents those of the stage's (q, q̇, u): the
    /// implicit-function derivative (`Data::fd_tangents`) along their ∂q, ∂q̇ and ∂τ.
    fn stage<const N: usize>(
        &self,
        model: &Robot,
        q: &[Jet<N>],
        qd: &[Jet<N>],
        u: &[Jet<N>],
    ) -> Vec<Jet<N>> {
        let value = |x: &[Jet<N>]| x.iter().map(|j| j.v).collect::<Vec<f64>>();
        let (qv, qdv) = (value(q), value(qd));
        let n = qv.len();
        // τ over the stage's own dual numbers carries its tangents in the step's directions.
        let tau = self.torques(q, qd, u);
        let tau_v = value(&tau);
        let tangents = |x: &[Jet<N>]| x.iter().flat_map(|j| *j.dense()).collect::<Vec<f64>>();
        let (dq, dqd, dtau) = (tangents(q), tangents(qd), tangents(&tau));
        with_data(|data| {
            data.fd_partials(model, &qv, &qdv, &tau_v);
            let mut out = vec![0.0; n * N];
            data.fd_tangents(&dq, &dqd, &dtau, N, &mut out);
            (data.qdd.iter().zip(out.chunks_exact(N)))
                .map(|(&v, d)| Jet::from_dense(v, d.try_into().expect("N tangents")))
                .collect()
        })
    }
}

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
use crate::arena::{AVec, Arena, CollectIn, zeros};
use crate::model::ModelConfig;
use crate::physics::dual::{Dual, Jet};
use crate::physics::integrator::States;
use crate::physics::multibody::{Model as Robot, with_data};
use crate::physics::templates::Template;

/// The most directions (2n + m) a step's Jacobian takes by the multibody derivatives.
const MULTIBODY_DIRS: usize = 64;

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

    /// The robot whose algorithms' derivatives give a step's Jacobian: a multibody model's
    /// of at most [`MULTIBODY_DIRS`] directions (beyond, dual numbers through the step do it).
    pub(super) fn jacobian_robot(&self) -> Option<&Robot> {
        let dirs = self.config.ndx() + self.config.m;
        let flat = self.config.space.is_flat();
        self.multibody
            .as_ref()
            .filter(|_| flat && dirs <= MULTIBODY_DIRS)
    }

    /// Per output coordinate of one state's step, the row [∂x'_i/∂x, ∂x'_i/∂u], in the
    /// arena; the jets' width the smallest that holds the state's directions (a 7-joint arm's
    /// 21 in 24, not 32: every jet operation is a loop over its width).
    pub(super) fn multibody_jacobian<'a>(
        &'a self,
        a: &'a Arena,
        model: &Robot,
        x: &[f64],
        u: &[f64],
    ) -> AVec<'a, f64> {
        match x.len() + u.len() {
            0..=8 => self.step_jacobian::<8>(a, model, x, u),
            9..=16 => self.step_jacobian::<16>(a, model, x, u),
            17..=24 => self.step_jacobian::<24>(a, model, x, u),
            25..=32 => self.step_jacobian::<32>(a, model, x, u),
            _ => self.step_jacobian::<MULTIBODY_DIRS>(a, model, x, u),
        }
    }

    fn step_jacobian<'a, const N: usize>(
        &'a self,
        a: &'a Arena,
        model: &Robot,
        x: &[f64],
        u: &[f64],
    ) -> AVec<'a, f64> {
        // A robot's joints are each one number: nq = nv = n.
        let (n, nx, dirs) = (self.config.nv(), x.len(), x.len() + u.len());
        let xu: AVec<f64> = x.iter().chain(u).copied().collect_in(a);
        let xu: AVec<Jet<N>> = Dual::seeded_in(a, &xu, &1.0, 0..dirs);
        let (xj, uj) = xu.split_at(nx);
        let xj = AVec::from_iter_in(xj.iter().cloned(), a);
        let states = States::new(&self.config.space, 1);
        let y = (self.config.integrator).step(&states, &xj, self.config.dt, |x: &AVec<Jet<N>>| {
            let mut dx = AVec::with_capacity_in(2 * n, a);
            dx.extend(x[n..].iter().cloned());
            dx.extend(self.stage(a, model, x, uj));
            dx
        });
        let mut rows = zeros(a, y.len() * dirs);
        for (row, y) in rows.chunks_exact_mut(dirs).zip(&y) {
            row.copy_from_slice(&y.dense()[..dirs]);
        }
        rows
    }

    /// q̈ at one stage of the integrator, its tangents those of the stage's (q, q̇, u): the
    /// implicit-function derivative (`Data::fd_tangents`) along their ∂q, ∂q̇ and ∂τ.
    fn stage<'a, const N: usize>(
        &'a self,
        a: &'a Arena,
        model: &Robot,
        x: &[Jet<N>],
        u: &[Jet<N>],
    ) -> AVec<'a, Jet<N>> {
        let (q, qd) = x.split_at(self.config.nq());
        let value = |x: &[Jet<N>]| -> AVec<f64> { x.iter().map(|j| j.v).collect_in(a) };
        let (qv, qdv) = (value(q), value(qd));
        let n = qv.len();
        // τ over the stage's own dual numbers carries its tangents in the step's directions.
        let tau = self.evaluate_in(a, self.rows(x, u), true);
        let tau_v = value(&tau);
        // Each jet's N tangents in one copy (a flat_map's unknown length grew the vector
        // by doublings, each a copy).
        let tangents = |x: &[Jet<N>]| -> AVec<f64> {
            let mut out = zeros(a, x.len() * N);
            for (o, j) in out.chunks_exact_mut(N).zip(x) {
                o.copy_from_slice(j.dense());
            }
            out
        };
        let (dq, dqd, dtau) = (tangents(q), tangents(qd), tangents(&tau));
        with_data(|data| {
            data.fd_partials(model, &qv, &qdv, &tau_v);
            let mut out = zeros(a, n * N);
            data.fd_tangents(&dq, &dqd, &dtau, N, &mut out);
            (data.qdd.iter().zip(out.chunks_exact(N)))
                .map(|(&v, d)| Jet::from_dense(v, d.try_into().expect("N tangents")))
                .collect_in(a)
        })
    }
}

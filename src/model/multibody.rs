//! URDF models in training on the multibody algorithms (docs/robots.md#training-by-the-adjoint):
//! q̈ = FD(q, q̇, τ; π) as one Burn op per batch ([`row_map`]), forward by the articulated-body
//! algorithm row by row and backward by forward dynamics' adjoint (λ = M⁻¹ḡ; ∂/∂τ = λ,
//! ∂/∂π = −Yᵀλ, ∂/∂(q, q̇) by a reverse pass over RNEA), O(n) per state each. τ = F − ∂V′/∂q
//! comes from the one assembly on Burn columns and π, the bodies' standard parameters, from
//! the physical values by Burn's ops, so the gradients reach θ, the networks and the forces
//! as Burn's autodiff carries them.

use std::sync::Arc;

use burn::tensor::Tensor;

use super::{Model, ModelConfig};
use crate::backend::{RowFn, RowFunction, row_map};
use crate::physics::multibody::adjoint::adjoint_at;
use crate::physics::multibody::regressor::with_parameters;
use crate::physics::multibody::{self, with_data};

/// Forward dynamics as a row function: a row is [q, q̇, τ], the parameters are π (ten per
/// body, `multibody::regressor`), the output q̈.
#[derive(Debug)]
pub(super) struct ForwardDynamics {
    /// The robot's tree; its inertias are replaced by π's on every call.
    model: multibody::Model,
}

impl ForwardDynamics {
    /// The op of `config`'s robot, when its q̈ comes from the multibody algorithms.
    pub(super) fn of(config: &ModelConfig) -> Option<RowFn> {
        let (t, gravity) = config.spec.multibody()?;
        let defaults = config.template()?.defaults();
        let model = t.multibody_model(&defaults, gravity);
        Some(RowFn(Arc::new(Self { model })))
    }

    fn n(&self) -> usize {
        self.model.n
    }
}

impl RowFunction for ForwardDynamics {
    fn input_width(&self) -> usize {
        3 * self.n()
    }

    fn output_width(&self) -> usize {
        self.n()
    }

    fn forward(&self, rows: &[f64], params: &[f64]) -> Vec<f64> {
        let (model, n) = (with_parameters(&self.model, params), self.n());
        let mut out = Vec::with_capacity(rows.len() / 3);
        with_data(|data| {
            for r in rows.chunks_exact(3 * n) {
                data.forward_dynamics(&model, &r[..n], &r[n..2 * n], &r[2 * n..]);
                out.extend_from_slice(&data.qdd);
            }
        });
        out
    }

    fn backward(
        &self,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (model, n) = (with_parameters(&self.model, params), self.n());
        let mut d_rows = Vec::with_capacity(rows.len());
        let mut d_params = vec![0.0; params.len()];
        let each = rows.chunks_exact(3 * n).zip(out.chunks_exact(n));
        for ((r, qdd), g) in each.zip(g.chunks_exact(n)) {
            let a = adjoint_at(&model, &r[..n], &r[n..2 * n], qdd.to_vec(), g);
            d_rows.extend(a.q.into_iter().chain(a.qd).chain(a.tau));
            for (d, p) in d_params.iter_mut().zip(a.pi) {
                *d += p;
            }
        }
        (d_rows, d_params)
    }
}

impl Model {
    /// q̈ of a model whose M is a URDF template's, by the multibody algorithms.
    pub(super) fn multibody_accel(
        &self,
        fd: &RowFn,
        q: Tensor<2>,
        qd: Tensor<2>,
        u: Tensor<2>,
    ) -> Tensor<2> {
        let (t, _) = self.config.spec.multibody().expect("a multibody model");
        let batch = q.dims()[0];
        let (tau, pi) = self.assemble(q.clone(), qd.clone(), u, |s, nets, inputs| {
            let physical = s
                .values
                .physical
                .expect("a template's M has physical values");
            (
                s.multibody_torques(nets, inputs),
                t.standard_parameters(physical),
            )
        });
        // A column that depends on no row (a joint without damping, friction or input) is
        // `[1, 1]`; rows need every column.
        let tau = tau.into_iter().map(|c| c.expand([batch, 1])).collect();
        let rows = Tensor::cat(vec![q, qd, Tensor::cat(tau, 1)], 1);
        row_map(fd, rows, Tensor::cat(pi, 1))
    }
}

impl Model {
    /// The same model on the template's M(q) and V(q) assembly instead of the multibody
    /// algorithms: the reference training's op is tested against, and a benchmark's baseline.
    pub fn assembled(mut self) -> Self {
        self.consts.multibody = None;
        self
    }

    /// Whether q̈ comes from the multibody algorithms.
    pub fn is_multibody(&self) -> bool {
        self.consts.multibody.is_some()
    }
}

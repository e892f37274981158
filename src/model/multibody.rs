//! URDF models in training on the multibody algorithms (docs/robots.md#training-by-the-adjoint):
//! q̈ = FD(q, q̇, τ; π) as one Burn op per batch ([`row_map`]), forward by the articulated-body
//! algorithm row by row and backward by forward dynamics' adjoint (λ = M⁻¹ḡ; ∂/∂τ = λ,
//! ∂/∂π = −Yᵀλ, ∂/∂(q, q̇) by λ contracted with RNEA's derivatives), O(n) per state each. τ = F − ∂V′/∂q
//! comes from the one assembly on Burn columns and π, the bodies' standard parameters, from
//! the physical values by Burn's ops, so the gradients reach θ, the networks and the forces
//! as Burn's autodiff carries them.

use std::sync::Arc;

use burn::tensor::Tensor;

use super::{Model, ModelConfig};
use crate::backend::{Kept, RowFn, RowFunction, row_map};
use crate::physics::multibody::data::PLACED;
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
        let model = robot(config)?;
        Some(RowFn(Arc::new(Self { model })))
    }

    fn n(&self) -> usize {
        self.model.n
    }

    /// q̈ row by row, and each row's placements (`Data::save_placements`) when `keep`.
    fn rows(&self, rows: &[f64], params: &[f64], keep: bool) -> (Vec<f64>, Vec<f64>) {
        let (model, n) = (with_parameters(&self.model, params), self.n());
        let batch = rows.len() / (3 * n);
        let mut out = Vec::with_capacity(batch * n);
        let mut placed = Vec::with_capacity(if keep {
            batch * PLACED * model.bodies.len()
        } else {
            0
        });
        with_data(|data| {
            for r in rows.chunks_exact(3 * n) {
                data.forward_dynamics(&model, &r[..n], &r[n..2 * n], &r[2 * n..]);
                out.extend_from_slice(&data.qdd);
                if keep {
                    data.save_placements(&mut placed);
                }
            }
        });
        (out, placed)
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
        self.rows(rows, params, false).0
    }

    fn forward_keeping(&self, rows: &[f64], params: &[f64]) -> (Vec<f64>, Kept) {
        let (out, placed) = self.rows(rows, params, true);
        (out, Kept::new(Placed(placed)))
    }

    fn backward(
        &self,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        self.backward_kept(&Kept::default(), rows, params, out, g)
    }

    /// The adjoint row by row, on the placements the forward pass kept when it did (the
    /// trigonometry and the products of rotations down the tree are a third of a row's
    /// kinematics, which the forward and backward passes would otherwise both compute).
    fn backward_kept(
        &self,
        kept: &Kept,
        rows: &[f64],
        params: &[f64],
        out: &[f64],
        g: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (model, n) = (with_parameters(&self.model, params), self.n());
        let placed = kept.take::<Placed>().map(|p| p.0);
        let per_row = PLACED * model.bodies.len();
        let mut d_rows = vec![0.0; rows.len()];
        let mut d_params = vec![0.0; params.len()];
        with_data(|data| {
            let each = rows.chunks_exact(3 * n).zip(out.chunks_exact(n));
            let each = each
                .zip(g.chunks_exact(n))
                .zip(d_rows.chunks_exact_mut(3 * n));
            for (i, (((r, qdd), g), d_row)) in each.enumerate() {
                let (q, qd) = (&r[..n], &r[n..2 * n]);
                match &placed {
                    Some(p) => data.kinematics_from(&model, &p[i * per_row..][..per_row], qd),
                    None => data.kinematics(&model, q, qd),
                }
                data.adjoint(&model, qdd, g, d_row, &mut d_params);
            }
        });
        d_params.iter_mut().for_each(|p| *p = -*p);
        (d_rows, d_params)
    }
}

/// The tree of `config`'s robot, when its q̈ comes from the multibody algorithms (its
/// inertias are the template's defaults: training replaces them by π's).
pub(super) fn robot(config: &ModelConfig) -> Option<multibody::Model> {
    let (t, gravity) = config.spec.multibody()?;
    let defaults = config.template()?.defaults();
    Some(t.multibody_model(&defaults, gravity))
}

/// The forward pass's placements, `PLACED` values per body and row.
struct Placed(Vec<f64>);

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
        let fused = self.is_fused();
        self.consts.multibody = None;
        self.on_path(fused)
    }

    /// Whether q̈ comes from the multibody algorithms.
    pub fn is_multibody(&self) -> bool {
        self.consts.multibody.is_some()
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::physics::multibody::regressor::standard_parameters;
    use crate::physics::templates::Template;
    use crate::physics::urdf::UrdfTemplate;

    /// The backward pass on the placements the forward pass kept equals, bit for bit, the one
    /// that computes them again (the kept values are copies of the same arithmetic), so a
    /// row or body mixed up in keeping them shows.
    #[test]
    fn backward_on_kept_placements_equals_recomputing_them() {
        let urdf = include_str!("../../tests/fixtures/urdf/robots/ur5.urdf");
        let t = Arc::new(UrdfTemplate::from_urdf(urdf).unwrap());
        let defaults = Template::Urdf(t.clone()).defaults();
        let fd = ForwardDynamics {
            model: t.multibody_model(&defaults, true),
        };
        let (n, batch) = (fd.n(), 5);
        let wave = |k: usize| (0.7 * k as f64).sin() * 1.5;
        let rows: Vec<f64> = (0..batch * 3 * n).map(wave).collect();
        let g: Vec<f64> = (0..batch * n).map(|k| wave(k + 11)).collect();
        let params = standard_parameters(&fd.model);
        let (out, kept) = fd.forward_keeping(&rows, &params);
        assert_eq!(out, fd.forward(&rows, &params));
        let fresh = fd.backward(&rows, &params, &out, &g);
        let reused = fd.backward_kept(&kept, &rows, &params, &out, &g);
        assert!(fresh.0.iter().any(|x| *x != 0.0));
        assert_eq!(reused, fresh);
    }
}

//! The Burn side of a model: constant tensors derived from its config, and a batch's tensors
//! as the columns the assembly ([`crate::physics::assembly`]) reads.

use burn::tensor::{Device, Tensor, TensorData};

use super::ModelConfig;
use super::mlp::InputTangent;
use super::params::{Components, ControlAffine, ForceParams, MassParams, Passive, PotentialParams};
use crate::backend::RowFn;
use crate::physics::assembly;
use crate::physics::dual::Dual;

/// Constant tensors derived from the config, built once per device.
#[derive(Debug, Clone)]
pub(super) struct Consts {
    pub(super) one: Tensor<2>,        // [1, 1]
    pub(super) q_mean: Tensor<2>,     // [1, n]
    pub(super) q_inv_std: Tensor<2>,  // [1, n]
    pub(super) dq_in: Tensor<2>,      // [n, n] = diag(1/σ_q): ∂(standardized q)/∂q
    pub(super) in_mean: Tensor<2>,    // [1, 2n+m] for [q, q̇, u]
    pub(super) in_inv_std: Tensor<2>, // [1, 2n+m]
    pub(super) acc_mean: Tensor<2>,   // [1, n]
    pub(super) acc_std: Tensor<2>,    // [1, n]
    pub(super) loss_w: Tensor<2>,     // [1, 2n] = [1…1, λ…λ]
    /// Present when some coordinate is an angle.
    pub(super) periodic: Option<Periodic>,
    /// Forward dynamics by the multibody algorithms, when M is a URDF template's.
    pub(super) multibody: Option<RowFn>,
    /// The whole step as one op (`model::fused`), when the model was asked to train so.
    pub(super) fused: Option<std::sync::Arc<super::fused::FusedStep>>,
}

/// What angles need: their networks' inputs are (sin q, cos q), their loss 2(1 − cos Δ).
#[derive(Debug, Clone)]
pub(super) struct Periodic {
    angles: Vec<bool>,
    /// Row k of the identity `[1, n]`: where ∂(an input from q_k)/∂q goes.
    unit: Vec<Tensor<2>>,
    /// Standardization of [q̇, u] `[1, n+m]`.
    qdu_mean: Tensor<2>,
    qdu_inv_std: Tensor<2>,
    /// `[1, 2n]`: 1 at the angles' q columns of the state (`wrap`), 1 elsewhere (`keep`).
    wrap: Tensor<2>,
    keep: Tensor<2>,
}

fn row(values: Vec<f64>, device: &Device) -> Tensor<2> {
    let k = values.len();
    Tensor::from_data(TensorData::new(values, [1, k]), device)
}

impl Consts {
    pub(super) fn new(c: &ModelConfig, device: &Device) -> Self {
        let s = &c.scaling;
        let n = c.n;
        let inv = |v: &[f64]| v.iter().map(|x| 1.0 / x).collect::<Vec<_>>();
        let mut diag = vec![0.0; n * n];
        for i in 0..n {
            diag[i * n + i] = 1.0 / s.q_std[i];
        }
        let cat = |a: &[f64], b: &[f64], c: &[f64]| [a, b, c].concat();
        let loss_w = [vec![1.0; n], vec![c.lambda; n]].concat();
        Self {
            one: row(vec![1.0], device),
            q_mean: row(s.q_mean.clone(), device),
            q_inv_std: row(inv(&s.q_std), device),
            dq_in: Tensor::from_data(TensorData::new(diag, [n, n]), device),
            in_mean: row(cat(&s.q_mean, &s.qdot_mean, &s.u_mean), device),
            in_inv_std: row(inv(&cat(&s.q_std, &s.qdot_std, &s.u_std)), device),
            acc_mean: row(s.acc_mean.clone(), device),
            acc_std: row(s.acc_std.clone(), device),
            loss_w: row(loss_w, device),
            periodic: (!c.periodic.is_empty()).then(|| Periodic {
                angles: (0..n).map(|k| c.is_periodic(k)).collect(),
                unit: (0..n)
                    .map(|k| row((0..n).map(|j| f64::from(j == k)).collect(), device))
                    .collect(),
                qdu_mean: row([&s.qdot_mean[..], &s.u_mean].concat(), device),
                qdu_inv_std: row(inv(&[&s.qdot_std[..], &s.u_std].concat()), device),
                wrap: row(
                    (0..2 * n).map(|k| f64::from(c.is_periodic(k))).collect(),
                    device,
                ),
                keep: row(
                    (0..2 * n).map(|k| f64::from(!c.is_periodic(k))).collect(),
                    device,
                ),
            }),
            multibody: super::multibody::ForwardDynamics::of(c),
            fused: None,
        }
    }

    /// The networks' input from q `[batch, q_in]`: standardized q, with (sin q, cos q) in
    /// place of an angle; with ∂input/∂q when asked.
    pub(super) fn q_input(
        &self,
        q: &Tensor<2>,
        tangent: bool,
    ) -> (Tensor<2>, Option<InputTangent>) {
        let Some(p) = &self.periodic else {
            let x = (q.clone() - self.q_mean.clone()) * self.q_inv_std.clone();
            return (x, tangent.then(|| self.dq_in.clone().into()));
        };
        let batch = q.dims()[0];
        let (mut inputs, mut tangents) = (vec![], vec![]);
        for (k, &angle) in p.angles.iter().enumerate() {
            // Column by column, only what is used: an unused tracked value slows training
            // (see `LazyColumns`).
            let qk = q.clone().narrow(1, k, 1);
            let e = || p.unit[k].clone();
            if angle {
                let (sin, cos) = (qk.clone().sin(), qk.cos());
                if tangent {
                    tangents.push(cos.clone() * e());
                    tangents.push(sin.clone().neg() * e());
                }
                inputs.extend([sin, cos]);
            } else {
                let inv = self.q_inv_std.clone().narrow(1, k, 1);
                if tangent {
                    tangents.push((e() * inv.clone()).repeat_dim(0, batch));
                }
                inputs.push((qk - self.q_mean.clone().narrow(1, k, 1)) * inv);
            }
        }
        let tangent = tangent.then(|| InputTangent::PerSample(Tensor::stack(tangents, 2)));
        (Tensor::cat(inputs, 1), tangent)
    }

    /// The networks' input from [q, q̇, u] `[batch, q_in + n + m]`.
    pub(super) fn full_input(&self, q: &Tensor<2>, qd: &Tensor<2>, u: &Tensor<2>) -> Tensor<2> {
        let Some(p) = &self.periodic else {
            let x = Tensor::cat(vec![q.clone(), qd.clone(), u.clone()], 1);
            return (x - self.in_mean.clone()) * self.in_inv_std.clone();
        };
        let rest = (Tensor::cat(vec![qd.clone(), u.clone()], 1) - p.qdu_mean.clone())
            * p.qdu_inv_std.clone();
        Tensor::cat(vec![self.q_input(q, false).0, rest], 1)
    }

    /// The per-entry loss of a state error `[batch, 2n]`: Δ², or 2(1 − cos Δ) for an angle
    /// (Δ² near zero, blind to whole turns).
    pub(super) fn squared_error(&self, err: Tensor<2>) -> Tensor<2> {
        match &self.periodic {
            None => err.square(),
            Some(p) => {
                let wrapped = err.clone().cos().neg().add_scalar(1.0).mul_scalar(2.0);
                err.square() * p.keep.clone() + wrapped * p.wrap.clone()
            }
        }
    }
}

/// The networks' outputs of a batch as columns.
pub(super) struct BurnNets {
    pub(super) mass: Option<Vec<Dual<Tensor<2>>>>,
    pub(super) potential_grad: Option<Vec<Tensor<2>>>,
    pub(super) force: Option<Vec<Tensor<2>>>,
    pub(super) damping: Option<Vec<Tensor<2>>>,
}

impl assembly::Networks<Tensor<2>> for BurnNets {
    fn mass(&self, j: usize) -> Dual<Tensor<2>> {
        self.mass.as_ref().expect("mass net")[j].clone()
    }
    fn potential_grad(&self, k: usize) -> Tensor<2> {
        self.potential_grad.as_ref().expect("potential net")[k].clone()
    }
    fn force(&self, j: usize) -> Tensor<2> {
        self.force.as_ref().expect("force net")[j].clone()
    }
    fn damping(&self, j: usize) -> Tensor<2> {
        self.damping.as_ref().expect("damping net")[j].clone()
    }
}

/// A batch's columns, each split off its tensor on first use: a tracked result that never
/// reaches the loss (say, columns of q that no part reads) keeps its whole autodiff graph
/// alive in Burn's registry, and every later backward pass slows down.
pub(super) struct LazyColumns<'a> {
    tensors: [&'a Tensor<2>; 3],
    cols: [std::cell::OnceCell<Vec<Tensor<2>>>; 3],
    one: &'a Tensor<2>,
}

impl<'a> LazyColumns<'a> {
    pub(super) fn new(
        q: &'a Tensor<2>,
        qd: &'a Tensor<2>,
        u: &'a Tensor<2>,
        one: &'a Tensor<2>,
    ) -> Self {
        Self {
            tensors: [q, qd, u],
            cols: Default::default(),
            one,
        }
    }

    fn get(&self, i: usize) -> &[Tensor<2>] {
        self.cols[i].get_or_init(|| columns(self.tensors[i]))
    }
}

impl assembly::Inputs<Tensor<2>> for LazyColumns<'_> {
    fn q(&self) -> &[Tensor<2>] {
        self.get(0)
    }
    fn qd(&self) -> &[Tensor<2>] {
        self.get(1)
    }
    fn u(&self) -> &[Tensor<2>] {
        self.get(2)
    }
    fn one(&self) -> Tensor<2> {
        self.one.clone()
    }
}

/// Splits `[batch, k]` into k columns `[batch, 1]`.
pub fn columns(x: &Tensor<2>) -> Vec<Tensor<2>> {
    let k = x.dims()[1];
    (0..k).map(|j| x.clone().narrow(1, j, 1)).collect()
}

/// Splits a network's output y `[batch, k]` and Jacobian J `[batch, n, k]` into k dual
/// columns `[batch, 1]` with tangents ∂y_j/∂q_i.
pub fn dual_columns(y: Tensor<2>, jac: Tensor<3>) -> Vec<Dual<Tensor<2>>> {
    let [batch, n, k] = jac.dims();
    let jflat = jac.reshape([batch, n * k]);
    (0..k)
        .map(|j| {
            let d = (0..n).map(|i| Some(jflat.clone().narrow(1, i * k + j, 1)));
            Dual::new(y.clone().narrow(1, j, 1), d)
        })
        .collect()
}

/// The structured model's networks on a batch, as columns (M's and V's with their
/// q-derivatives, in forward mode).
pub(super) fn networks(
    c: &Consts,
    p: &Components,
    n: usize,
    [q, qd, u]: [&Tensor<2>; 3],
) -> BurnNets {
    let with_tangent = || {
        let (x, dx_dq) = c.q_input(q, true);
        (x, dx_dq.expect("asked for the tangent"))
    };
    BurnNets {
        mass: match &p.mass {
            Some(MassParams::Net(net)) => {
                let (x, dx_dq) = with_tangent();
                let (y, jac) = net.forward_jacobian(x, dx_dq);
                Some(dual_columns(y, jac))
            }
            _ => None,
        },
        potential_grad: match &p.potential {
            Some(PotentialParams::Net(net)) => {
                let (x, dx_dq) = with_tangent();
                let jac = net.jacobian(x, dx_dq);
                Some(columns(&jac.reshape([q.dims()[0], n])))
            }
            _ => None,
        },
        force: match &p.forces {
            Some(ForceParams::Net(net)) => Some(columns(&net.forward(c.full_input(q, qd, u)))),
            Some(ForceParams::ControlAffine(ControlAffine { b_net, .. }))
            | Some(ForceParams::Passive(Passive { b_net, .. })) => {
                Some(columns(&b_net.forward(c.q_input(q, false).0)))
            }
            _ => None,
        },
        // [q, q̇]: the full input without its last m columns, u's.
        damping: match &p.forces {
            Some(ForceParams::Passive(f)) => {
                let x = c.full_input(q, qd, u);
                let width = x.dims()[1] - u.dims()[1];
                Some(columns(&f.damping_net.forward(x.narrow(1, 0, width))))
            }
            _ => None,
        },
    }
}

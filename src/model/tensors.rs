//! The Burn side of a model: constant tensors derived from its config, and a batch's tensors
//! as the columns the assembly ([`super::assembly`]) reads.

use burn::tensor::{Device, Tensor, TensorData};

use super::ModelConfig;
use super::assembly;
use super::dual::Dual;

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
        }
    }
}

/// The networks' outputs of a batch as columns.
pub(super) struct BurnNets {
    pub(super) mass: Option<Vec<Dual<Tensor<2>>>>,
    pub(super) potential_grad: Option<Vec<Tensor<2>>>,
    pub(super) force: Option<Vec<Tensor<2>>>,
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

/// Trainable values in training: `[1, 1]` tensors, tracked.
impl assembly::Coef<Tensor<2>> for Tensor<2> {
    fn times(&self, x: &Tensor<2>) -> Tensor<2> {
        x.clone() * self.clone()
    }
    fn value(&self, _like: &Tensor<2>) -> Tensor<2> {
        self.clone()
    }
    fn mul_div(&self, mul: f64, div: f64) -> Self {
        self.clone().mul_scalar(mul / div)
    }
}

/// Splits `[batch, k]` into k columns `[batch, 1]`.
pub fn columns(x: &Tensor<2>) -> Vec<Tensor<2>> {
    let k = x.dims()[1];
    (0..k).map(|j| x.clone().narrow(1, j, 1)).collect()
}

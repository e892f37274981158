//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod fused;
pub mod jacobian_form;
pub mod plans;
pub mod urdf;

use burn::module::{Module, ModuleVisitor, Param};
use burn::tensor::{Device, Gradients, Tensor, TensorData};
use graybox::model::params_io::import;
use graybox::model::spec::ModelSpec;
use graybox::model::{Model, ModelConfig};
use graybox::physics::integrator::Integrator;
use graybox::physics::scaling::Scaling;
use graybox::physics::space::Space;
use graybox::physics::templates::Template;
use graybox::rng::Rng;

pub fn tensor(rows: &[Vec<f64>], device: &Device) -> Tensor<2> {
    let w = rows[0].len();
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Tensor::from_data(TensorData::new(flat, [rows.len(), w]), device)
}

pub fn host(t: Tensor<2>) -> Vec<Vec<f64>> {
    let [_, w] = t.dims();
    let v: Vec<f64> = t.into_data().iter::<f64>().collect();
    v.chunks(w).map(<[f64]>::to_vec).collect()
}

pub fn host1(t: Tensor<2>) -> Vec<f64> {
    t.into_data().iter::<f64>().collect()
}

pub type Rows = Vec<Vec<f64>>;

/// Random paper-range states and inputs: q ~ U(−π, π), q̇ ~ U(−10, 10), u ~ N(0, 120²).
pub fn paper_samples(n: usize, m: usize, count: usize, seed: u64) -> (Rows, Rows, Rows) {
    let mut r = Rng::new(seed);
    let mut q = vec![];
    let mut qd = vec![];
    let mut u = vec![];
    for _ in 0..count {
        q.push(
            (0..n)
                .map(|_| r.uniform_in(-std::f64::consts::PI, std::f64::consts::PI))
                .collect(),
        );
        qd.push((0..n).map(|_| r.uniform_in(-10.0, 10.0)).collect());
        u.push((0..m).map(|_| 120.0 * r.normal()).collect());
    }
    (q, qd, u)
}

/// A model config with scalings of roughly paper-data size, without needing a dataset.
pub fn config(spec: ModelSpec, n: usize, m: usize) -> ModelConfig {
    let mut s = Scaling::identity(n, n, m);
    s.q_std = vec![1.8; n];
    s.qdot_std = vec![5.8; n];
    s.u_std = vec![120.0; m];
    s.acc_std = vec![20.0; n];
    s.force_scale = vec![30.0; n];
    ModelConfig {
        spec,
        space: Space::flat(n, &[]),
        m,
        dt: 0.01,
        integrator: Integrator::Rk4,
        lambda: 1.0,
        scaling: s,
    }
}

pub fn model(
    name: &str,
    template: Option<Template>,
    n: usize,
    m: usize,
    seed: u64,
    device: &Device,
) -> Model {
    let spec = ModelSpec::named(name, template).expect("valid model name");
    Model::init(config(spec, n, m), None, seed, device).expect("model builds")
}

/// The paper's double pendulum (appendix), written out independently of the library:
/// explicit Christoffel terms and a 2×2 inverse.
pub fn double_pendulum_accel(p: &[f64; 9], q: &[f64], qd: &[f64], u: &[f64]) -> [f64; 2] {
    let [m1, m2, l1, l2, g, b1, b2, e1, e2] = *p;
    let i1 = m1 * l1 * l1 / 3.0;
    let i2 = m2 * l2 * l2 / 3.0;
    let c2 = q[1].cos();
    let m11 = i1 + i2 + m2 * l1 * l1 + m2 * l1 * l2 * c2;
    let m12 = i2 + 0.5 * m2 * l1 * l2 * c2;
    let m22 = i2;
    let h = m2 * l1 * l2 * q[1].sin();
    // c_i = Σ_jk ∂M_ij/∂q_k q̇_j q̇_k − ½ Σ_jk ∂M_jk/∂q_i q̇_j q̇_k with ∂M11/∂q2 = −h, ∂M12/∂q2 = −h/2
    let c1 = -h * qd[0] * qd[1] - 0.5 * h * qd[1] * qd[1];
    let c2_ = 0.5 * h * qd[0] * qd[0];
    let dv1 = 0.5 * m1 * g * l1 * q[0].sin()
        + m2 * g * (l1 * q[0].sin() + 0.5 * l2 * (q[0] + q[1]).sin());
    let dv2 = 0.5 * m2 * g * l2 * (q[0] + q[1]).sin();
    let r1 = b1 * u[0] + e1 * qd[0] - c1 - dv1;
    let r2 = b2 * u[1] + e2 * qd[1] - c2_ - dv2;
    let det = m11 * m22 - m12 * m12;
    [(m22 * r1 - m12 * r2) / det, (-m12 * r1 + m11 * r2) / det]
}

pub const PAPER: [f64; 9] = [10.0, 10.0, 1.0, 1.0, 10.0, 1.0, 1.0, -0.5, -0.5];

/// max|a − b| / max(1, max|b|): the issues' tolerance measure.
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let num = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let den = b.iter().map(|y| y.abs()).fold(1.0, f64::max);
    num / den
}

/// Solves A x = b by Gaussian elimination with partial pivoting (reference only).
pub fn gauss_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            let pivot_row = a[c].clone();
            for (x, p) in a[r][c..].iter_mut().zip(&pivot_row[c..]) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x
}

/// Moves every parameter off its initial value so that zero-initialized parts (η, K, constant
/// L) are exercised too.
pub fn perturb(model: &Model, dev: &Device) -> Model {
    let mut r = Rng::new(99);
    let arrays: Vec<_> = model
        .params
        .export()
        .into_iter()
        .map(|mut a| {
            for v in &mut a.values {
                *v += 0.3 * r.normal();
            }
            a
        })
        .collect();
    let params = import(model.params.clone(), &arrays, dev).unwrap();
    Model::from_parts(model.config.clone(), params, dev)
}

/// Every parameter tensor's gradient in `grads`, flattened, in the module's visiting order
/// (zeros for one the loss does not reach).
pub struct GradCollector<'a> {
    pub grads: &'a Gradients,
    pub out: Vec<Vec<f64>>,
}

impl ModuleVisitor for GradCollector<'_> {
    fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
        let t = p.val();
        let numel = t.dims().iter().product();
        self.out.push(match t.grad(self.grads) {
            Some(g) => g.into_data().iter::<f64>().collect(),
            None => vec![0.0; numel],
        });
    }
}

/// One step's loss on `rows` random rows (|x| ≤ 2, |u| ≤ 5, targets like x) and each
/// parameter tensor's gradient.
pub fn random_loss_and_gradients(model: &Model, dev: &Device, rows: usize) -> (f64, Vec<Vec<f64>>) {
    let (n, m) = (model.config.nv(), model.config.m);
    let mut r = Rng::new(8);
    let mut draw = |w: usize, s: f64| -> Vec<Vec<f64>> {
        (0..rows)
            .map(|_| (0..w).map(|_| r.uniform_in(-s, s)).collect())
            .collect()
    };
    let (x, u, y) = (draw(2 * n, 2.0), draw(m, 5.0), draw(2 * n, 2.0));
    let loss: Tensor<1> = model.loss_sum(tensor(&x, dev), tensor(&u, dev), tensor(&y, dev));
    value_and_gradients(model, loss)
}

/// The torque loss on `rows` random rows (|q|, |q̇|, |q̈| ≤ 2, |u| ≤ 5) and every parameter's
/// gradient.
pub fn random_torque_loss_and_gradients(
    model: &Model,
    dev: &Device,
    rows: usize,
) -> (f64, Vec<Vec<f64>>) {
    let (n, m) = (model.config.nv(), model.config.m);
    let mut r = Rng::new(9);
    let x: Vec<Vec<f64>> = (0..rows)
        .map(|_| {
            let mut row: Vec<f64> = (0..3 * n).map(|_| r.uniform_in(-2.0, 2.0)).collect();
            row.extend((0..m).map(|_| r.uniform_in(-5.0, 5.0)));
            row
        })
        .collect();
    value_and_gradients(model, model.torque_sum(tensor(&x, dev)))
}

fn value_and_gradients(model: &Model, loss: Tensor<1>) -> (f64, Vec<Vec<f64>>) {
    let value = loss.clone().into_data().iter::<f64>().next().unwrap();
    let grads = loss.backward();
    let mut gc = GradCollector {
        grads: &grads,
        out: vec![],
    };
    model.params.visit(&mut gc);
    (value, gc.out)
}

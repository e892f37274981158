//! The plans' shared references: the paper's double-pendulum swing-up, its closed-form RK4,
//! and a linear-quadratic problem with its batch least-squares answer.

use graybox::control::linalg::Mat;
use graybox::control::plan::{Dynamics, Plan, PlanRequest};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::model::{Model, ModelConfig};
use graybox::physics::integrator::Integrator;
use graybox::physics::scaling::Scaling;
use graybox::physics::templates::Template;

use super::{PAPER, double_pendulum_accel, gauss_solve};

pub fn diag(v: &[f64]) -> Mat {
    let n = v.len();
    let mut m = Mat::zeros(n, n);
    for (i, x) in v.iter().enumerate() {
        m.data[i * n + i] = *x;
    }
    m
}

pub fn swing_up(horizon: usize) -> PlanRequest {
    let weights = [
        diag(&[1.0, 1.0, 0.1, 0.1]),
        diag(&[1e-4, 1e-4]),
        diag(&[1000.0, 1000.0, 100.0, 100.0]),
    ];
    let goal = vec![std::f64::consts::PI, 0.0, 0.0, 0.0];
    PlanRequest {
        u_min: Some(vec![-120.0; 2]),
        u_max: Some(vec![120.0; 2]),
        ..PlanRequest::new(vec![0.0; 4], goal, horizon, weights)
    }
}

pub fn true_double_pendulum() -> Evaluator {
    let file =
        ModelFile::from_template(&Template::DoublePendulum, &PAPER, 0.1, Integrator::Rk4).unwrap();
    Evaluator::from_file(&file).unwrap()
}

/// One RK4 step of the closed-form double pendulum (tests/common), independent of graybox.
pub fn reference_step(x: &[f64], u: &[f64], dt: f64) -> Vec<f64> {
    let f = |x: &[f64]| -> Vec<f64> {
        let a = double_pendulum_accel(&PAPER, &x[..2], &x[2..], u);
        vec![x[2], x[3], a[0], a[1]]
    };
    let at = |k: &[f64], h: f64| x.iter().zip(k).map(|(a, b)| a + h * b).collect::<Vec<_>>();
    let k1 = f(x);
    let k2 = f(&at(&k1, dt / 2.0));
    let k3 = f(&at(&k2, dt / 2.0));
    let k4 = f(&at(&k3, dt));
    (0..4)
        .map(|i| x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
        .collect()
}

/// A white-box model whose dynamics are linear: constant mass matrix, quadratic potential,
/// constant input gain and force.
pub fn linear_model(dt: f64) -> Evaluator {
    Evaluator::from_file(&linear_file(dt, 1.0)).unwrap()
}

/// `linear_model`'s file with its stiffness (the quadratic potential) times `stiffness`.
pub fn linear_file(dt: f64, stiffness: f64) -> ModelFile {
    let spec: ModelSpec = ModelSpec::parse(
        r#"{"mass": "constant", "potential": "quadratic", "forces": "constant_affine"}"#,
        None,
    )
    .unwrap();
    let config = ModelConfig {
        spec,
        space: graybox::physics::space::Space::flat(2, &[]),
        m: 2,
        dt,
        integrator: Integrator::Rk4,
        lambda: 1.0,
        scaling: Scaling::identity(2, 2, 2),
    };
    let dev = graybox::backend::device(
        graybox::backend::Backend::Flex,
        graybox::backend::Precision::F32,
    )
    .unwrap();
    let model = Model::init(config.clone(), None, 0, &dev).unwrap();
    let mut params = model.params.export();
    for a in &mut params {
        a.values = match a.name.as_str() {
            "mass_const" => vec![0.3, 0.2, -0.1],
            "potential_quad" => vec![4.0 * stiffness, 1.0 * stiffness, 2.5 * stiffness],
            "b_const" => vec![1.0, 0.3, -0.2, 0.8],
            "eta" => vec![-0.2, -0.1],
            other => panic!("unexpected value {other}"),
        };
    }
    ModelFile::new(config, params, None)
}

/// From a displaced state to another over `t` steps, unbounded, with weights on everything.
pub fn linear_request(t: usize) -> PlanRequest {
    let weights = [
        diag(&[2.0, 1.0, 0.3, 0.2]),
        diag(&[0.05, 0.1]),
        diag(&[20.0, 10.0, 3.0, 2.0]),
    ];
    PlanRequest {
        max_iterations: 50,
        tolerance: 1e-9,
        ..PlanRequest::new(
            vec![0.5, -0.3, 0.1, 0.2],
            vec![0.2, 0.4, 0.0, 0.0],
            t,
            weights,
        )
    }
}

/// The end of the swing-up `p` (T steps, |u| ≤ 120) tracked from `x0` by its own gains on
/// the closed-form RK4.
pub fn track_swing_up(p: &Plan, x0: &[f64]) -> Vec<f64> {
    let mut x = x0.to_vec();
    for (t, k) in p.gains.k.iter().enumerate() {
        let u: Vec<f64> = (0..2)
            .map(|i| {
                let fb: f64 = (0..4).map(|j| k.at(i, j) * (x[j] - p.x[t * 4 + j])).sum();
                (p.u[t * 2 + i] - fb).clamp(-120.0, 120.0)
            })
            .collect();
        x = reference_step(&x, &u, 0.1);
    }
    x
}

/// The discrete LQ optimum's inputs `[T, m]` of the linear model's one-step map, by batch
/// least squares over the stacked rollout X = Φ + Γ U.
pub fn batch_least_squares(eval: &Evaluator, req: &PlanRequest) -> Vec<f64> {
    let t = req.horizon;
    // x_{t+1} = A x_t + B u_t + c: A, B from the exact Jacobian, c from one step at 0.
    let (a, b) = eval.linearize(&[0.0; 4], &[0.0; 2]);
    let (a, b) = (&a[0], &b[0]);
    let c = eval.step(&[0.0; 4], &[0.0; 2]);
    // X = Φ + Γ U stacked over t = 1..T; least squares on the weighted residuals.
    let (nx, m) = (4, 2);
    let mut phi = vec![req.x0.clone()];
    let mut gamma: Vec<Vec<Vec<f64>>> = vec![vec![vec![0.0; t * m]; nx]];
    for s in 0..t {
        let (px, gx) = (&phi[s], &gamma[s]);
        let next_phi: Vec<f64> = (0..nx)
            .map(|i| (0..nx).map(|j| a.at(i, j) * px[j]).sum::<f64>() + c[i])
            .collect();
        let mut next_g = vec![vec![0.0; t * m]; nx];
        for (i, row) in next_g.iter_mut().enumerate() {
            for (k, v) in row.iter_mut().enumerate() {
                *v = (0..nx).map(|j| a.at(i, j) * gx[j][k]).sum::<f64>();
            }
            for k in 0..m {
                row[s * m + k] += b.at(i, k);
            }
        }
        phi.push(next_phi);
        gamma.push(next_g);
    }
    // Normal equations: (Σ Γ_tᵀ W_t Γ_t + R̄) U = Σ Γ_tᵀ W_t (g − Φ_t).
    let dim = t * m;
    let mut h = vec![vec![0.0; dim]; dim];
    let mut rhs = vec![0.0; dim];
    for s in 1..=t {
        let w = if s == t { &req.qf } else { &req.q };
        for i in 0..nx {
            let wi = w.at(i, i);
            let e = req.goal[i] - phi[s][i];
            for k in 0..dim {
                rhs[k] += gamma[s][i][k] * wi * e;
                for l in 0..dim {
                    h[k][l] += gamma[s][i][k] * wi * gamma[s][i][l];
                }
            }
        }
    }
    for s in 0..t {
        for k in 0..m {
            h[s * m + k][s * m + k] += req.r.at(k, k);
        }
    }
    gauss_solve(h, rhs)
}

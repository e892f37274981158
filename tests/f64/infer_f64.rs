//! The f64 inference path against the Burn path (the trainer's own math) and against finite
//! differences, in f64.

use crate::common;
#[path = "infer_f64/energy.rs"]
mod energy;

use burn::tensor::Device;
use common::*;
use graybox::backend::{Backend, Precision, device};
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::{ModelSpec, NAMED};
use graybox::model::{Model, ModelConfig};
use graybox::physics::templates::Template;

fn f64_device() -> Device {
    device(Backend::Flex, Precision::F64).expect("f64 device")
}

/// A case: its name, spec, n, m and which coordinates are angles.
type Case = (String, ModelSpec, usize, usize, Vec<bool>);

fn cases() -> Vec<Case> {
    let mut v: Vec<Case> = plain_cases()
        .into_iter()
        .map(|(name, spec, n, m)| (name, spec, n, m, vec![]))
        .collect();
    let dp = Some(Template::DoublePendulum);
    // Angles as (sin q, cos q): every network kind that reads q (M, V, B, F, naive).
    for (name, template, n, m, periodic) in [
        ("MVF", dp.clone(), 2, 2, vec![true, true]),
        ("MVB", Some(Template::Cartpole), 2, 1, vec![false, true]),
        ("naive", dp.clone(), 2, 2, vec![true, false]),
    ] {
        v.push((
            format!("{name}/periodic {periodic:?}"),
            ModelSpec::named(name, template).unwrap(),
            n,
            m,
            periodic,
        ));
    }
    // URDF robots (the rigid-body tree over Burn columns vs f64 and dual numbers): the
    // 4-DoF arm white-box with its Coulomb friction, and with residual networks on top.
    let dir = format!("{}/tests/fixtures/urdf", env!("CARGO_MANIFEST_DIR"));
    let arm = std::fs::read_to_string(format!("{dir}/arm4.urdf")).unwrap();
    let arm = Template::Urdf(std::sync::Arc::new(
        graybox::physics::urdf::UrdfTemplate::from_urdf(&arm).unwrap(),
    ));
    v.push((
        "W-B/urdf arm4".into(),
        ModelSpec::named("W-B", Some(arm.clone())).unwrap(),
        4,
        4,
        arm.periodic(),
    ));
    // Residual networks on the template's potential and forces.
    let residual = r#"{"mass": "template",
        "potential": {"type": "template", "residual": {"type": "mlp", "hidden": [16, 16]}},
        "forces": {"type": "template", "residual": "mlp"}}"#;
    v.push((
        "W-B+residuals/double_pendulum".into(),
        ModelSpec::parse(residual, dp.clone()).unwrap(),
        2,
        2,
        vec![],
    ));
    v.push((
        "W-B+residuals/urdf arm4".into(),
        ModelSpec::parse(residual, Some(arm.clone())).unwrap(),
        4,
        4,
        arm.periodic(),
    ));
    // Wider than a dual number's eight directions: M's and V's q-derivatives (10) and a
    // linearization's (x, u) directions (23) run in groups (`dual::groups`), on the tape too.
    v.push((
        "wide/MVF n=10, periodic".into(),
        ModelSpec::named("MVF", None).unwrap(),
        10,
        3,
        (0..10).map(|k| k % 3 == 0).collect(),
    ));
    v.push((
        "W-B+residuals/periodic".into(),
        ModelSpec::parse(residual, dp).unwrap(),
        2,
        2,
        vec![true, true],
    ));
    v
}

fn plain_cases() -> Vec<(String, ModelSpec, usize, usize)> {
    let mut v = vec![];
    for name in NAMED {
        v.push((
            format!("{name}/double_pendulum"),
            ModelSpec::named(name, Some(Template::DoublePendulum)).unwrap(),
            2,
            2,
        ));
        v.push((
            format!("{name}/cartpole"),
            ModelSpec::named(name, Some(Template::Cartpole)).unwrap(),
            2,
            1,
        ));
    }
    v.push((
        "W-B/pendulum".into(),
        ModelSpec::named("W-B", Some(Template::Pendulum)).unwrap(),
        1,
        1,
    ));
    // Passive forces: B(q)u − D(q, q̇)q̇, n ≠ m.
    v.push((
        "passive/mlp".into(),
        ModelSpec::parse(
            r#"{"mass": "mlp", "potential": "mlp", "forces": "passive"}"#,
            None,
        )
        .unwrap(),
        3,
        2,
    ));
    let custom = r#"{"kind":"structured","mass":{"type":"constant"},"potential":{"type":"quadratic"},"forces":{"type":"constant_affine"}}"#;
    v.push((
        "constant/quadratic/constant_affine".into(),
        ModelSpec::parse(custom, None).unwrap(),
        3,
        2,
    ));
    v
}

fn build(
    spec: ModelSpec,
    n: usize,
    m: usize,
    periodic: Vec<bool>,
    dev: &Device,
) -> (Model, Evaluator) {
    let mut cfg: ModelConfig = config(spec, n, m);
    cfg.space = graybox::physics::space::Space::flat(n, &periodic);
    cfg.scaling.q_mean = vec![0.1; n];
    cfg.scaling.u_mean = vec![-2.0; m];
    let model = Model::init(cfg, None, 3, dev).unwrap();
    // Perturbed weights (0.3 each) make a network M of ten coordinates nearly singular and
    // the step overflow (|x'| ~ 1e29), where nothing compares: the wide case keeps its
    // initial weights, random and not small.
    let model = if n <= 8 { perturb(&model, dev) } else { model };
    let file = ModelFile::new(model.config.clone(), model.params.export(), None);
    let file = ModelFile::from_bytes(&file.to_bytes().unwrap()).unwrap();
    (model, Evaluator::from_file(&file).unwrap())
}

/// One RK4 step of every parameterization: the evaluator equals the training step to 1e-9
/// (both are f64; they differ only in operation order and tanh's formula), one state at a
/// time (f64 scalars) and as one batch of 150 (columns through the structure, two threads).
#[test]
fn evaluator_matches_the_training_step_for_every_parameterization() {
    let dev = f64_device();
    for (name, spec, n, m, periodic) in cases() {
        let (model, eval) = build(spec, n, m, periodic, &dev);
        let (q, qd, u) = paper_samples(n, m, 150, 5);
        let x: Vec<Vec<f64>> = q
            .iter()
            .zip(&qd)
            .map(|(a, b)| [a.clone(), b.clone()].concat())
            .collect();
        let burn = host(model.step(tensor(&x, &dev), tensor(&u, &dev)));
        let (batched, _) = eval.predict(&x.concat(), &u.concat(), false);
        let err = rel_err(&batched, &burn.concat());
        assert!(err < 1e-9, "{name} batched: {err:e}");
        for i in 0..x.len() {
            let ours = eval.step(&x[i], &u[i]);
            let err = rel_err(&ours, &burn[i]);
            assert!(
                err < 1e-9,
                "{name}: {err:e}\n ours {ours:?}\n burn {:?}",
                burn[i]
            );
        }
    }
}

/// A and B of the one-step map (dual numbers through the Jacobian recursion, second
/// derivatives of M and V included) vs central differences of `step` with h = 1e-6:
/// truncation ~h² and rounding ~ε/h ≈ 1e-10 on O(1) entries.
#[test]
fn linearize_matches_central_differences() {
    let dev = f64_device();
    for (name, spec, n, m, periodic) in cases().into_iter().filter(|c| {
        c.0.starts_with("MVF/")
            || c.0.starts_with("W-B")
            || c.0.starts_with("MVB/d")
            || c.0.starts_with("naive/d")
            || c.0.contains("periodic")
            || c.0.starts_with("wide/")
    }) {
        let (_, eval) = build(spec, n, m, periodic, &dev);
        let (q, qd, u) = paper_samples(n, m, 3, 9);
        for i in 0..q.len() {
            let x: Vec<f64> = [q[i].clone(), qd[i].clone()].concat();
            let (a, b) = eval.linearize_batch(&x, &u[i]);
            let h = 1e-6;
            let nx = x.len();
            let mut fd_a = vec![0.0; nx * nx];
            let mut fd_b = vec![0.0; nx * m];
            for k in 0..nx + m {
                let (mut xp, mut xm, mut up, mut um) =
                    (x.clone(), x.clone(), u[i].clone(), u[i].clone());
                if k < nx {
                    xp[k] += h;
                    xm[k] -= h;
                } else {
                    up[k - nx] += h;
                    um[k - nx] -= h;
                }
                let (fp, fm) = (eval.step(&xp, &up), eval.step(&xm, &um));
                for r in 0..nx {
                    let d = (fp[r] - fm[r]) / (2.0 * h);
                    if k < nx {
                        fd_a[r * nx + k] = d
                    } else {
                        fd_b[r * m + k - nx] = d
                    }
                }
            }
            assert!(
                rel_err(&a, &fd_a) < 1e-6,
                "{name} A: {:e}",
                rel_err(&a, &fd_a)
            );
            assert!(
                rel_err(&b, &fd_b) < 1e-6,
                "{name} B: {:e}",
                rel_err(&b, &fd_b)
            );
        }
    }
}

/// A batch of 100 linearizations (dual numbers over columns, two threads) equals the points
/// one at a time (dual numbers over f64) for every parameterization: the same operations per
/// sample, so anything beyond rounding is a batching bug.
#[test]
fn batched_linearize_equals_single_points() {
    let dev = f64_device();
    for (name, spec, n, m, periodic) in cases() {
        let (_, eval) = build(spec, n, m, periodic, &dev);
        let (q, qd, u) = paper_samples(n, m, 100, 4);
        let x: Vec<f64> = (0..q.len())
            .flat_map(|i| [q[i].clone(), qd[i].clone()].concat())
            .collect();
        let (a, b) = eval.linearize_batch(&x, &u.concat());
        let (nx, mm) = (2 * n, m);
        for i in 0..q.len() {
            let (ai, bi) = eval.linearize_batch(&x[i * nx..(i + 1) * nx], &u[i]);
            let ea = rel_err(&a[i * nx * nx..(i + 1) * nx * nx], &ai);
            let eb = rel_err(&b[i * nx * mm..(i + 1) * nx * mm], &bi);
            assert!(
                ea < 1e-12 && eb < 1e-12,
                "{name} point {i}: A {ea:e}, B {eb:e}"
            );
        }
    }
}

/// The continuous dynamics direct collocation constrains by: f = (q̇, q̈) with q̈ the model's
/// acceleration as Predict reports it, and its Jacobian against central differences of f
/// (tolerance as for Linearize above), for every kind of part, batched.
#[test]
fn continuous_dynamics_and_its_jacobian_match_predict_and_central_differences() {
    use graybox::control::dircol::Continuous;
    let dev = f64_device();
    for (name, spec, n, m, periodic) in cases().into_iter().filter(|c| {
        c.0.starts_with("MVF/")
            || c.0.starts_with("W-B")
            || c.0.starts_with("naive/d")
            || c.0.contains("periodic")
            || c.0.starts_with("wide/")
    }) {
        let (_, eval) = build(spec, n, m, periodic, &dev);
        let (q, qd, u) = paper_samples(n, m, 40, 11);
        let x: Vec<f64> = (0..q.len())
            .flat_map(|i| [q[i].clone(), qd[i].clone()].concat())
            .collect();
        let u: Vec<f64> = u.concat();
        let f = eval.derivative(&x, &u);
        let acc = eval.predict(&x, &u, true).1.unwrap();
        let nx = 2 * n;
        for (i, row) in f.chunks(nx).enumerate() {
            assert_eq!(row[..n], x[i * nx + n..(i + 1) * nx], "{name}: q̇");
            assert!(
                rel_err(&row[n..], &acc[i * n..(i + 1) * n]) < 1e-12,
                "{name}: q̈"
            );
        }
        let (a, b) = eval.derivative_jacobian(&x, &u);
        let h = 1e-6;
        for i in [0, 17, 39] {
            let (xi, ui) = (&x[i * nx..(i + 1) * nx], &u[i * m..(i + 1) * m]);
            let columns = central_columns(|x, u| eval.derivative(x, u), xi, ui, h);
            for (k, fd) in columns.iter().enumerate() {
                let exact = column(&a[i], &b[i], k);
                assert!(
                    rel_err(&exact, fd) < 1e-6,
                    "{name} row {i} direction {k}: {exact:?} vs {fd:?}"
                );
            }
        }
    }
}

/// A robot on the multibody algorithms (arm4, with friction): f's q̈ equals Predict's (which
/// takes the multibody path) and its Jacobian (dual numbers through the generic path) matches
/// central differences.
#[test]
fn a_robots_continuous_dynamics_match_its_multibody_path() {
    use graybox::control::dircol::Continuous;
    use graybox::physics::integrator::Integrator;
    let urdf = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/urdf/arm4.urdf"
    ))
    .unwrap();
    let t = Template::from_document(&serde_json::json!({"kind": "urdf", "urdf": urdf})).unwrap();
    let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
    let eval = Evaluator::from_file(&file).unwrap();
    let (n, m) = (eval.config.nv(), eval.config.m);
    let (q, qd, u) = paper_samples(n, m, 5, 4);
    let x: Vec<f64> = (0..5)
        .flat_map(|i| [q[i].clone(), qd[i].clone()].concat())
        .collect();
    let u: Vec<f64> = u.concat().iter().map(|v| v * 0.05).collect();
    let f = eval.derivative(&x, &u);
    let acc = eval.predict(&x, &u, true).1.unwrap();
    let nx = 2 * n;
    for i in 0..5 {
        assert!(rel_err(&f[i * nx + n..(i + 1) * nx], &acc[i * n..(i + 1) * n]) < 1e-9);
    }
    let (a, b) = eval.derivative_jacobian(&x[..nx], &u[..m]);
    // The multibody algorithms run in the root frame, which rounds q̈ to about 1e-12 of its
    // size (measured: central differences along the base's vertical axis, whose exact
    // derivative is 0, shrink as 1/h from h = 1e-7 to 1e-3). So each difference carries up to
    // 1e-11·|f|/h of rounding beside its O(h²) truncation; h = 1e-5 keeps both below 1e-6 of
    // the derivatives' scale at these states (|f| ≈ 300).
    let h = 1e-5;
    let size = f[..nx].iter().fold(0.0f64, |s, v| s.max(v.abs()));
    let rounding = 1e-11 * size / h;
    let columns = central_columns(|x, u| eval.derivative(x, u), &x[..nx], &u[..m], h);
    for (k, fd) in columns.iter().enumerate() {
        let exact = column(&a[0], &b[0], k);
        let scale = fd.iter().fold(1.0f64, |s, v| s.max(v.abs()));
        assert!(
            rel_err(&exact, fd) < 1e-6 + rounding / scale,
            "direction {k}: {exact:?} vs {fd:?}"
        );
    }
}

/// Central differences of `f` at (x, u), one column per direction: x's, then u's.
fn central_columns(
    f: impl Fn(&[f64], &[f64]) -> Vec<f64>,
    x: &[f64],
    u: &[f64],
    h: f64,
) -> Vec<Vec<f64>> {
    (0..x.len() + u.len())
        .map(|k| {
            let (mut xp, mut xm, mut up, mut um) = (x.to_vec(), x.to_vec(), u.to_vec(), u.to_vec());
            if k < x.len() {
                xp[k] += h;
                xm[k] -= h;
            } else {
                up[k - x.len()] += h;
                um[k - x.len()] -= h;
            }
            let (fp, fm) = (f(&xp, &up), f(&xm, &um));
            fp.iter()
                .zip(&fm)
                .map(|(p, m)| (p - m) / (2.0 * h))
                .collect()
        })
        .collect()
}

/// Column `k` of [A B].
fn column(
    a: &graybox::control::linalg::Mat,
    b: &graybox::control::linalg::Mat,
    k: usize,
) -> Vec<f64> {
    (0..a.rows)
        .map(|r| {
            if k < a.cols {
                a.at(r, k)
            } else {
                b.at(r, k - a.cols)
            }
        })
        .collect()
}

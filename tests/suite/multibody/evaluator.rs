//! URDF models evaluate on the multibody algorithms (`infer::multibody`): q̈, one step and its
//! Jacobians equal the template assembly's (`Evaluator::assembled`, M(q) = Σ JᵀIJ and V(q)
//! over dual numbers) for white-box models of real robots (mimic joints and branches
//! included) and for models whose residual networks, network potential or control-affine
//! forces were trained; the Jacobians also equal central differences of the step.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;
use graybox::rng::Rng;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{TrainConfig, Trainer};

use super::common::urdf::fixture_path;
use super::err;

fn template(name: &str) -> Template {
    let urdf = std::fs::read_to_string(fixture_path(name, "urdf")).unwrap();
    Template::Urdf(Arc::new(UrdfTemplate::from_urdf(&urdf).unwrap()))
}

fn reloaded(file: &ModelFile) -> Evaluator {
    Evaluator::from_file(&ModelFile::from_bytes(&file.to_bytes().unwrap()).unwrap()).unwrap()
}

/// The multibody evaluator and the assembled one agree at `states` random states (|q| ≤ 2,
/// |q̇| ≤ 3, |u| ≤ 5): q̈, the step and both Jacobians to 1e-9 of max(1, |ref|). Both are f64
/// evaluations of the same mechanics by different formulas (recursions over the tree vs
/// Σ JᵀIJ, derivatives by the implicit function theorem vs dual numbers through the
/// Cholesky factor), so rounding (~1e-13) separates them; a wrong frame, sign, gravity or
/// chain-rule term moves them by far more.
fn agree(what: &str, e: &Evaluator, states: usize) {
    assert!(
        e.is_multibody(),
        "{what}: a URDF model with M from the template"
    );
    let reference = e.clone().assembled();
    assert!(!reference.is_multibody());
    let (n, m) = (e.config.nv(), e.config.m);
    let mut rng = Rng::new(3);
    let mut draw = |k: usize, r: f64| (0..k).map(|_| rng.uniform_in(-r, r)).collect::<Vec<_>>();
    for s in 0..states {
        let (q, qd, u) = (draw(n, 2.0), draw(n, 3.0), draw(m, 5.0));
        let (a, a_ref) = (e.accel(&q, &qd, &u), reference.accel(&q, &qd, &u));
        assert!(err(&a, &a_ref) < 1e-9, "{what} {s}: q̈ {a:?} vs {a_ref:?}");
        let x = [q, qd].concat();
        let (p, p_ref) = (
            e.predict(&x, &u, false).0,
            reference.predict(&x, &u, false).0,
        );
        assert!(err(&p, &p_ref) < 1e-9, "{what} {s}: x' {p:?} vs {p_ref:?}");
        let ((ja, jb), (ja_ref, jb_ref)) =
            (e.linearize_batch(&x, &u), reference.linearize_batch(&x, &u));
        assert!(
            err(&ja, &ja_ref) < 1e-9,
            "{what} {s}: A {ja:?} vs {ja_ref:?}"
        );
        assert!(
            err(&jb, &jb_ref) < 1e-9,
            "{what} {s}: B {jb:?} vs {jb_ref:?}"
        );
    }
}

/// White-box models of the vendored robots: the UR5, the Panda (its second finger a mimic
/// joint: CRBA + Cholesky), Solo 12 (a branching tree), the Kinova (continuous joints); a
/// batch of states goes state by state and must equal the states one at a time.
#[test]
fn white_box_robots_equal_the_assembly() {
    for (name, states) in [
        ("robots/ur5", 4),
        ("robots/panda", 3),
        ("robots/solo12", 2),
        ("robots/kinova", 2),
        ("robots/iiwa", 2),
        ("arm4", 6),
        ("tree", 6),
    ] {
        let t = template(name);
        let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
        let e = reloaded(&file);
        agree(name, &e, states);
        let (n, m) = (e.config.nv(), e.config.m);
        let mut rng = Rng::new(5);
        let x: Vec<f64> = (0..40 * 2 * n).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let u: Vec<f64> = (0..40 * m).map(|_| rng.uniform_in(-1.0, 1.0)).collect();
        let (batch, acc) = e.predict(&x, &u, true);
        let (a, b) = e.linearize_batch(&x, &u);
        for (k, (xs, us)) in x.chunks(2 * n).zip(u.chunks(m)).enumerate() {
            let (one, one_acc) = e.predict(xs, us, true);
            assert_eq!(one, batch[k * 2 * n..(k + 1) * 2 * n], "{name} row {k}");
            assert_eq!(one_acc.unwrap(), acc.as_ref().unwrap()[k * n..(k + 1) * n]);
            let (ak, bk) = e.linearize_batch(xs, us);
            assert_eq!(
                ak,
                a[k * 4 * n * n..(k + 1) * 4 * n * n],
                "{name} A row {k}"
            );
            assert_eq!(
                bk,
                b[k * 2 * n * m..(k + 1) * 2 * n * m],
                "{name} B row {k}"
            );
        }
    }
}

/// Models whose other parts are networks, trained for an epoch so that every network's
/// output is nonzero: V and F residuals on the template's (τ carries −∂V_net/∂q), a network
/// potential (the recursion then runs without gravity), and control-affine forces.
#[test]
fn trained_parts_on_a_urdf_model_equal_the_assembly() {
    let t = template("arm4");
    let cfg = SimConfig {
        count: 64,
        ..SimConfig::default()
    };
    let data = simulate(&t, t.defaults(), &cfg).unwrap();
    let device = graybox::backend::device(
        graybox::backend::Backend::Flex,
        graybox::backend::Precision::F32,
    )
    .unwrap()
    .autodiff();
    let residual = r#"{"type": "template", "residual": {"type": "mlp", "hidden": [8]}}"#;
    for (what, spec) in [
        (
            "residuals",
            format!(r#"{{"mass": "template", "potential": {residual}, "forces": {residual}}}"#),
        ),
        (
            "network potential",
            r#"{"mass": "template", "potential": {"type": "mlp", "hidden": [8]},
                "forces": "template"}"#
                .into(),
        ),
        (
            "control-affine forces",
            r#"{"mass": "template", "potential": "template",
                "forces": {"type": "control_affine", "hidden": [8]}}"#
                .into(),
        ),
    ] {
        let spec = ModelSpec::parse(&spec, Some(t.clone())).unwrap();
        let train = TrainConfig {
            epochs: 2,
            batch_size: 32,
            val_fraction: 0.0,
            ..TrainConfig::default()
        };
        let mut tr = Trainer::new("t", spec, &[], &data, None, train, &device).unwrap();
        tr.run_epoch(&AtomicBool::new(false)).unwrap();
        agree(what, &reloaded(&tr.model_file()), 4);
    }
}

/// The Jacobians of one step equal central differences of the step (h = 1e-6: truncation
/// ~h²·|x'''| ≈ 1e-12 and rounding ~1e-16/h = 1e-10, so 1e-6 of max(1, |ref|) is loose enough
/// for both and tight enough for any missing chain-rule term), with damping and Coriolis
/// forces at work (the Panda's joints are damped; |q̇| up to 3).
#[test]
fn multibody_jacobians_equal_central_differences() {
    for name in ["robots/ur5", "robots/panda"] {
        let t = template(name);
        let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
        let e = reloaded(&file);
        let (n, m) = (e.config.nv(), e.config.m);
        let mut rng = Rng::new(9);
        for _ in 0..3 {
            let x: Vec<f64> = (0..2 * n)
                .map(|i| rng.uniform_in(-1.0, 1.0) * if i < n { 2.0 } else { 3.0 })
                .collect();
            let u: Vec<f64> = (0..m).map(|_| rng.uniform_in(-5.0, 5.0)).collect();
            let (a, b) = e.linearize_batch(&x, &u);
            let h = 1e-6;
            let column = |k: usize| -> Vec<f64> {
                let (mut xp, mut xm, mut up, mut um) = (x.clone(), x.clone(), u.clone(), u.clone());
                if k < 2 * n {
                    xp[k] += h;
                    xm[k] -= h;
                } else {
                    up[k - 2 * n] += h;
                    um[k - 2 * n] -= h;
                }
                let (p, q) = (e.predict(&xp, &up, false).0, e.predict(&xm, &um, false).0);
                p.iter().zip(q).map(|(p, q)| (p - q) / (2.0 * h)).collect()
            };
            let mut fd_a = vec![0.0; 4 * n * n];
            let mut fd_b = vec![0.0; 2 * n * m];
            for k in 0..2 * n + m {
                for (i, v) in column(k).into_iter().enumerate() {
                    if k < 2 * n {
                        fd_a[i * 2 * n + k] = v;
                    } else {
                        fd_b[i * m + k - 2 * n] = v;
                    }
                }
            }
            assert!(err(&a, &fd_a) < 1e-6, "{name}: A {a:?} vs {fd_a:?}");
            assert!(err(&b, &fd_b) < 1e-6, "{name}: B {b:?} vs {fd_b:?}");
        }
    }
}

/// The true system of a URDF template (`sim::TemplateSystem`, what `simulate` steps) runs the
/// multibody algorithms too: its q̈ equals the assembled model's and its energies the
/// template's M and V (½ q̇ᵀMq̇, V(q)), to 1e-9 of max(1, |ref|) as above.
#[test]
fn the_true_system_of_a_urdf_template_is_multibody() {
    use graybox::sim::TemplateSystem;
    for name in ["robots/panda", "robots/iiwa"] {
        let t = template(name);
        let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
        let reference = reloaded(&file).assembled();
        let sys = TemplateSystem::new(t.clone(), t.defaults());
        let (n, m) = (t.n(), t.m());
        let mut rng = Rng::new(13);
        for s in 0..3 {
            let mut draw = |k: usize| {
                (0..k)
                    .map(|_| rng.uniform_in(-2.0, 2.0))
                    .collect::<Vec<_>>()
            };
            let (q, qd, u) = (draw(n), draw(n), draw(m));
            let (a, a_ref) = (sys.acceleration(&q, &qd, &u), reference.accel(&q, &qd, &u));
            assert!(err(&a, &a_ref) < 1e-9, "{name} {s}: q̈ {a:?} vs {a_ref:?}");
            let p = t.defaults();
            let mass = t.mass(&p, &q);
            let kinetic: f64 = (0..n)
                .map(|i| {
                    (0..n)
                        .map(|j| 0.5 * qd[i] * mass[i][j] * qd[j])
                        .sum::<f64>()
                })
                .sum();
            let (k, v) = sys.energy(&q, &qd);
            let v_ref = t.potential(&p, &q);
            assert!(err(&[k, v], &[kinetic, v_ref]) < 1e-9, "{name} {s}: T, V");
        }
    }
}

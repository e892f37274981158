//! Formula templates (docs/robots.md#formula-templates) against independent references: the built-in templates'
//! equations written as formulas give the same M, V, F and q̈ in f64; a mechanism no built-in
//! covers (a Furuta pendulum) conserves energy unforced; bad documents are refused naming the
//! field and the offset.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use graybox::arena::Arena;
use graybox::backend::{Backend, Precision};
use graybox::error::Error;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::dual::Dual;
use graybox::physics::dynamics::{constants, white_box_acceleration};
use graybox::physics::formula_template::FormulaTemplate;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::sim::TemplateSystem;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{TrainConfig, Trainer};
use serde_json::{Value, json};

#[path = "formula/identify.rs"]
mod identify;
#[path = "formula/limits.rs"]
mod limits;
#[path = "formula/recursive.rs"]
mod recursive;

/// A document of `examples/templates/` (the ones the README points to).
fn example(name: &str) -> Value {
    let path = format!(
        "{}/examples/templates/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    );
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// The built-in double pendulum (the paper's appendix) as a formula.
fn double_pendulum() -> Value {
    example("double_pendulum")
}

fn cartpole() -> Value {
    json!({
        "kind": "formula", "name": "cartpole", "coordinates": ["x", "theta"],
        "periodic": [false, true], "inputs": ["f"],
        "parameters": {
            "mc": {"value": 1.0, "positive": true}, "mp": {"value": 0.5, "positive": true},
            "l": {"value": 1.0, "positive": true}, "g": {"value": 10.0, "positive": true},
            "b": {"value": 1.0}, "eta_x": {"value": -0.1}, "eta_th": {"value": -0.1}
        },
        "mass": [["mc + mp", "mp*l*cos(theta)"], ["mp*l*cos(theta)", "mp*l^2"]],
        "potential": "-mp*g*l*cos(theta)",
        "forces": ["b*f + eta_x*x_dot", "eta_th*theta_dot"]
    })
}

/// A Furuta (rotary inverted) pendulum: arm angle θ, pendulum angle α (0 upright), a torque
/// on the arm; Cazzolato & Prime (2011) with the pendulum's centre of mass at Lp/2.
fn furuta() -> Value {
    example("furuta")
}

fn template(doc: &Value) -> FormulaTemplate {
    FormulaTemplate::parse(&doc.to_string()).unwrap_or_else(|e| panic!("{e}"))
}

/// The formula's parameter values in the built-in template's order (formula parameters are
/// in alphabetical order).
fn builtin_values(f: &FormulaTemplate, t: &Template) -> Vec<f64> {
    let d = f.defaults();
    t.params()
        .iter()
        .map(|p| d[f.param_names().iter().position(|n| *n == p.name).unwrap()])
        .collect()
}

fn accel(f: &FormulaTemplate, p: &[f64], q: &[f64], qd: &[f64], u: &[f64]) -> Vec<f64> {
    let pd = constants(p);
    white_box_acceleration(
        &Arena::new(),
        &graybox::physics::space::Space::flat(q.len(), &[]),
        |q| f.mass(&pd, q),
        |q| f.potential(&pd, q),
        &f.forces(p, q, qd, u),
        q,
        qd,
    )
    .to_vec()
}

/// Relative agreement to 1e-12: the same arithmetic in a different order rounds differently
/// by a few ulps, amplified at most by M's condition number (≲ 1e3 here).
fn close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0),
        "{what}: {a} vs {b}"
    );
}

#[test]
fn builtin_templates_written_as_formulas_give_the_same_dynamics() {
    for (doc, t) in [
        (double_pendulum(), Template::DoublePendulum),
        (cartpole(), Template::Cartpole),
    ] {
        let f = template(&doc);
        assert_eq!((f.n(), f.m()), (t.n(), t.m()));
        let p = f.defaults();
        let pb = builtin_values(&f, &t);
        assert_eq!(pb, t.defaults(), "the documents use the built-in defaults");
        let sys = TemplateSystem::new(t.clone(), pb.clone());
        let mut rng = Rng::new(7);
        for _ in 0..100 {
            let mut r = |s: f64| {
                (0..t.n())
                    .map(|_| rng.uniform_in(-s, s))
                    .collect::<Vec<f64>>()
            };
            let (q, qd) = (r(std::f64::consts::PI), r(10.0));
            let u: Vec<f64> = (0..t.m()).map(|_| 50.0 * rng.normal()).collect();
            let (mf, mb) = (f.mass(&p, &q), t.mass(&pb, &q));
            for i in 0..t.n() {
                for j in 0..t.n() {
                    close(mf[i][j], mb[i][j], "M");
                }
            }
            close(f.potential(&p, &q), t.potential(&pb, &q), "V");
            for (a, b) in f
                .forces(&p, &q, &qd, &u)
                .iter()
                .zip(t.forces(&pb, &q, &qd, &u))
            {
                close(*a, b, "F");
            }
            for (a, b) in accel(&f, &p, &q, &qd, &u)
                .iter()
                .zip(sys.acceleration(&q, &qd, &u))
            {
                close(*a, b, "q̈");
            }
        }
    }
}

#[test]
fn furuta_pendulum_conserves_energy_unforced() {
    let f = template(&furuta());
    let p = f.defaults();
    let energy = |q: &[f64], qd: &[f64]| {
        let m = f.mass(&p, q);
        let t: f64 = (0..2)
            .flat_map(|i| (0..2).map(move |j| (i, j)))
            .map(|(i, j)| 0.5 * qd[i] * m[i][j] * qd[j])
            .sum();
        (t, f.potential(&p, q))
    };
    for (q0, qd0) in [
        ([0.3, 0.2], [1.0, -2.0]),
        ([-2.0, 2.5], [3.0, 4.0]),
        ([1.0, -0.1], [0.0, 0.5]),
    ] {
        let (t0, v0) = energy(&q0, &qd0);
        let mut x: Vec<f64> = q0.iter().chain(&qd0).copied().collect();
        let mut drift: f64 = 0.0;
        for _ in 0..1000 {
            let space = graybox::physics::space::Space::flat(2, &[]);
            let states = graybox::physics::integrator::States::new(&space, 1);
            x = Integrator::Rk4.step(&states, &x, 1e-3, |x: &Vec<f64>| {
                let qdd = accel(&f, &p, &x[..2], &x[2..], &[0.0]);
                x[2..].iter().chain(&qdd).copied().collect()
            });
            let (tk, vk) = energy(&x[..2], &x[2..]);
            drift = drift.max((tk + vk - t0 - v0).abs());
        }
        // RK4's energy error at Δt = 1e-3 over 1 s is ~1e-10 of the energy.
        assert!(drift < 1e-6 * (t0.abs() + v0.abs()), "drift {drift}");
    }
    // Dual numbers through the formula: ∂M/∂α against a central difference.
    let q = [0.4, 0.9];
    let qv = [
        Dual::variable(q[0], 0, 2, 1.0),
        Dual::variable(q[1], 1, 2, 1.0),
    ];
    let m = f.mass(&constants(&p), &qv);
    let h = 1e-6;
    let fd =
        (f.mass(&p, &[q[0], q[1] + h])[0][0] - f.mass(&p, &[q[0], q[1] - h])[0][0]) / (2.0 * h);
    let ad = m[0][0].tangent(1).copied().unwrap_or(0.0);
    // Central difference: truncation ~h² ≈ 1e-12, rounding ~1e-16/h ≈ 1e-10.
    assert!((ad - fd).abs() < 1e-8 * fd.abs(), "∂M00/∂α: {ad} vs {fd}");
}

/// Each bad document: the error names the field (and, in expressions, the offset).
#[test]
fn bad_documents_are_refused_naming_field_and_offset() {
    let with = |path: &[&str], v: Value| {
        let mut d = cartpole();
        let mut at = &mut d;
        for k in &path[..path.len() - 1] {
            at = match k.parse::<usize>() {
                Ok(i) => &mut at[i],
                Err(_) => &mut at[*k],
            };
        }
        let last = path[path.len() - 1];
        match last.parse::<usize>() {
            Ok(i) => at[i] = v,
            Err(_) => at[last] = v,
        }
        d.to_string()
    };
    let cases: Vec<(String, &str, &str)> = vec![
        ("{\"kind\": \"formula\",".into(), "template", "EOF"),
        (with(&["kind"], json!("urdf")), "kind", "formula"),
        (
            with(&["mass", "0", "1"], json!("mp*l*cos(theta) + foo")),
            "mass[0][1]",
            "unknown name 'foo'",
        ),
        (
            with(&["mass", "1", "1"], json!("mp*l^2 + theta_dot")),
            "mass[1][1]",
            "a velocity 'theta_dot' at offset 9",
        ),
        (
            with(&["potential"], json!("f*x")),
            "potential",
            "an input 'f' at offset 0",
        ),
        (
            with(&["mass", "1", "0"], json!("mp*l*sin(theta)")),
            "mass[1][0]",
            "symmetric",
        ),
        (
            with(&["forces"], json!(["f"])),
            "forces",
            "expected 2 entries",
        ),
        (
            with(&["mass", "1"], json!(["mp*l*cos(theta)"])),
            "mass[1]",
            "expected 2 entries",
        ),
        (
            with(&["forces", "0"], json!("b*f + * x_dot")),
            "forces[0]",
            "offset 6",
        ),
        (
            with(&["forces", "1"], json!("cosine(theta)")),
            "forces[1]",
            "unknown function 'cosine'",
        ),
        (
            cartpole()
                .to_string()
                .replace("\"value\":10.0", "\"value\":1e400"),
            "parameters.g.value",
            "out of range",
        ),
        (
            with(&["parameters", "mc", "value"], json!(-1.0)),
            "parameters.mc.value",
            "> 0",
        ),
        (
            with(&["inputs"], json!(["x"])),
            "inputs[0]",
            "already the name of coordinates[0]",
        ),
        (
            with(&["coordinates", "1"], json!("sin")),
            "coordinates[1]",
            "function",
        ),
        (
            with(&["parameters", "x_dot"], json!({"value": 1.0})),
            "parameters.x_dot",
            "the velocity of coordinates[0]",
        ),
        (with(&["periodic"], json!([true])), "periodic", "expected 2"),
        (
            with(&["mass", "0", "0"], json!("mp - mc")),
            "mass",
            "positive definite",
        ),
        (with(&["extra"], json!(1)), "extra", "unknown field"),
    ];
    for (doc, field, needle) in cases {
        match FormulaTemplate::parse(&doc) {
            Err(Error::Unprocessable { field: f, message }) => {
                assert_eq!(f, field, "{message}");
                assert!(message.contains(needle), "{field}: {message}");
            }
            other => panic!("{field}: expected a 422, got {other:?}"),
        }
    }
}

fn flex() -> burn::tensor::Device {
    graybox::backend::device(Backend::Flex, Precision::F32)
        .unwrap()
        .autodiff()
}

/// W-B on the double pendulum written as a formula trains like the built-in template (same
/// data, seed and start; its parameters in another order), and its model file, which embeds
/// the document, loads alone and predicts as the trained model does.
#[test]
fn formula_white_box_trains_like_the_builtin_and_its_file_stands_alone() {
    let formula = Template::Formula(Arc::new(template(&double_pendulum())));
    let builtin = Template::DoublePendulum;
    let sim = |seed| {
        simulate(
            &builtin,
            builtin.defaults(),
            &SimConfig {
                count: 64,
                seed,
                ..SimConfig::default()
            },
        )
        .unwrap()
    };
    let (data, val) = (sim(1), sim(2));
    let cfg = TrainConfig {
        epochs: 3,
        batch_size: 16,
        ..TrainConfig::default()
    };
    // ±30% starts, by name.
    let init: Vec<(String, f64)> = [
        ("m1", 13.0),
        ("m2", 7.0),
        ("l1", 1.3),
        ("l2", 0.7),
        ("g", 8.0),
        ("b1", 1.2),
        ("b2", 0.8),
        ("eta1", -0.4),
        ("eta2", -0.6),
    ]
    .map(|(k, v)| (k.to_string(), v))
    .to_vec();
    let losses = |t: &Template| {
        let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
        let mut tr =
            Trainer::new("W-B", spec, &init, &data, Some(&val), cfg.clone(), &flex()).unwrap();
        tr.run(&AtomicBool::new(false), |_, _| {}).unwrap();
        let r = tr.report();
        (
            r.history
                .iter()
                .map(|h| (h.train_loss, h.val_loss.unwrap()))
                .collect::<Vec<_>>(),
            tr.model_file(),
        )
    };
    let (a, _) = losses(&builtin);
    let (b, file) = losses(&formula);
    // f32 training: the same operations in another order differ by rounding (~1e-6 relative).
    for ((ta, va), (tb, vb)) in a.iter().zip(&b) {
        assert!(
            (ta - tb).abs() <= 1e-4 * ta.abs() && (va - vb).abs() <= 1e-4 * va.abs(),
            "{a:?} vs {b:?}"
        );
    }
    assert!(b.last().unwrap().1 < b[0].1, "the loss decreases: {b:?}");

    let bytes = file.to_bytes().unwrap();
    assert!(String::from_utf8_lossy(&bytes).contains("\"graybox.model/2\""));
    let loaded = ModelFile::from_bytes(&bytes).unwrap();
    assert_eq!(loaded.config.template(), file.config.template());
    let (e1, e2) = (
        Evaluator::from_file(&file).unwrap(),
        Evaluator::from_file(&loaded).unwrap(),
    );
    let x = [0.3, -0.2, 1.0, 0.5];
    assert_eq!(
        e1.predict(&x, &[3.0, -2.0], true),
        e2.predict(&x, &[3.0, -2.0], true)
    );
}

/// A one-coordinate document (θ, an input u) with these parameters and potential.
fn fixed_pendulum(parameters: Value, potential: &str) -> Template {
    let doc = json!({
        "kind": "formula", "name": "fixed", "coordinates": ["th"], "inputs": ["u"],
        "parameters": parameters, "mass": [["1"]], "potential": potential, "forces": ["u"]
    });
    Template::Formula(Arc::new(template(&doc)))
}

/// Issue 26: W-B on a template with nothing to train (no parameter, or none that a white-box
/// part uses) passed every check and then panicked in the backward pass ("Tensor::backward
/// requires a tracked autodiff tensor"); the trainer returns an error naming the template. A
/// network part has something to train whatever the template.
#[test]
fn a_white_box_model_with_nothing_to_train_is_an_error_not_a_panic() {
    let pendulum = Template::Pendulum;
    let data = simulate(
        &pendulum,
        pendulum.defaults(),
        &SimConfig {
            count: 16,
            seed: 3,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let cfg = TrainConfig {
        epochs: 1,
        batch_size: 8,
        val_fraction: 0.0,
        ..TrainConfig::default()
    };
    let train = |model: &str, t: &Template| {
        let spec = ModelSpec::named(model, Some(t.clone())).unwrap();
        Trainer::new(model, spec, &[], &data, None, cfg.clone(), &flex())
            .and_then(|mut tr| tr.run(&AtomicBool::new(false), |_, _| {}))
    };
    for t in [
        fixed_pendulum(json!({}), "-10*cos(th)"),
        fixed_pendulum(json!({"k": {"value": 2.0}}), "-10*cos(th)"),
        // Used, but only where training never differentiates (V enters as ∂V/∂q): found by
        // the trainer at its first step rather than at submission.
        fixed_pendulum(json!({"k": {"value": 2.0}}), "k - 10*cos(th)"),
    ] {
        match train("W-B", &t) {
            Err(Error::Invalid { field, message }) => {
                assert_eq!(field, "template", "{message}");
                assert!(message.contains("no trainable parameter"), "{message}");
            }
            other => panic!("expected a refusal, got {other:?}"),
        }
        train("MVF", &t).unwrap();
    }
}

/// Issue 26: a document's values and names follow the rules of a job's `init` and of every
/// name. Values of 1e7, 1e300 (any parameter) or 1e-320 (a positive one) passed and then failed
/// at the first epoch with a non-finite loss; names of 20 000 characters or with NUL, ESC or
/// a right-to-left override were stored. The bounds themselves are accepted.
#[test]
fn document_values_and_names_follow_the_one_rule() {
    let refused = |doc: Value| match FormulaTemplate::parse(&doc.to_string()) {
        Err(Error::Unprocessable { field, message }) => (field, message),
        other => panic!("expected a 422, got {other:?}"),
    };
    let set = |path: &str, v: Value| {
        let mut d = cartpole();
        *d.pointer_mut(path).unwrap() = v;
        d
    };
    for (path, v, needle) in [
        ("/parameters/g/value", 1e7, "≤ 1e6"),
        ("/parameters/b/value", -1e300, "≤ 1e6"),
        ("/parameters/mc/value", 1e-320, "at least 1e-6"),
        ("/parameters/l/value", 5e-7, "at least 1e-6"),
    ] {
        let (field, message) = refused(set(path, json!(v)));
        let name = path.split('/').nth(2).unwrap();
        assert_eq!(field, format!("parameters.{name}.value"), "{message}");
        assert!(message.contains(needle), "{v}: {message}");
    }
    for name in [
        "x".repeat(20_000),
        "a\0b".into(),
        "a\u{1b}[31m".into(),
        "ab\u{202E}cd".into(),
    ] {
        let (field, message) = refused(set("/name", json!(name)));
        assert_eq!(field, "name", "{message}");
    }
    // A parameter's name is an identifier, and no longer than any other name.
    let mut long = cartpole();
    let p = long["parameters"].as_object_mut().unwrap();
    p.insert("k".repeat(201), json!({"value": 1.0}));
    let (field, message) = refused(long);
    assert_eq!(field, "parameters", "{message}");
    assert!(
        message.contains("200 characters") && message.len() < 300,
        "{message}"
    );

    let mut edge = set("/parameters/g/value", json!(1e6));
    edge["parameters"]["mc"]["value"] = json!(1e-6);
    edge["parameters"]["b"]["value"] = json!(-1e6);
    edge["parameters"]["eta_x"]["value"] = json!(1e-300);
    edge["name"] = json!("é".repeat(200));
    template(&edge);
}

//! Learned residuals on white-box parts and periodic coordinates, trained:
//! a residual closes the gap a missing term leaves in a white-box model, and wrapped angles
//! train as well as unwrapped ones once the coordinates are marked periodic. Each run has a
//! fixed seed and a stated number of epochs; the comparisons are between runs of this test.

use std::f64::consts::PI;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use graybox::backend::{Backend, Precision};
use graybox::data::Dataset;
use graybox::model::Model;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::formula_template::FormulaTemplate;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;
use graybox::sim::{SimConfig, TemplateSystem, simulate, true_step};
use graybox::train::trainer::evaluate;
use graybox::train::{TrainConfig, Trainer};
use serde_json::json;

fn flex() -> burn::tensor::Device {
    graybox::backend::device(Backend::Flex, Precision::F32)
        .unwrap()
        .autodiff()
}

/// The paper's double pendulum with a torsion spring −k q₂ at the elbow (V + ½ k q₂²),
/// which the built-in template lacks.
fn sprung_double_pendulum(k: f64) -> Template {
    let doc = json!({
        "kind": "formula", "name": "sprung_double_pendulum",
        "coordinates": ["q1", "q2"], "inputs": ["u1", "u2"],
        "parameters": {
            "m1": {"value": 10.0, "positive": true}, "m2": {"value": 10.0, "positive": true},
            "l1": {"value": 1.0, "positive": true}, "l2": {"value": 1.0, "positive": true},
            "g": {"value": 10.0, "positive": true}, "k": {"value": k, "positive": true},
            "b1": {"value": 1.0}, "b2": {"value": 1.0}, "eta1": {"value": -0.5}, "eta2": {"value": -0.5}
        },
        "mass": [
            ["m1*l1^2/3 + m2*l2^2/3 + m2*l1^2 + m2*l1*l2*cos(q2)", "m2*l2^2/3 + m2*l1*l2*cos(q2)/2"],
            ["m2*l2^2/3 + m2*l1*l2*cos(q2)/2", "m2*l2^2/3"]
        ],
        "potential": "-m1*g*l1*cos(q1)/2 - m2*g*(l1*cos(q1) + l2*cos(q1 + q2)/2) + k*q2^2/2",
        "forces": ["b1*u1 + eta1*q1_dot", "b2*u2 + eta2*q2_dot"]
    });
    Template::Formula(Arc::new(FormulaTemplate::parse(&doc.to_string()).unwrap()))
}

fn best_val(spec: ModelSpec, data: &Dataset, val: &Dataset, cfg: TrainConfig) -> f64 {
    let mut tr = Trainer::new("test", spec, &[], data, Some(val), cfg, &flex()).unwrap();
    tr.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    tr.best_val_loss().unwrap()
}

/// Data from the sprung pendulum (k = 200 N·m/rad: its torque at q₂ = 1 is a tenth of the
/// links' gravity torques); W-B with the true values of every other parameter cannot fit the
/// spring and stalls at a floor; W-B with a residual potential, or a residual force, learns
/// it and ends below a tenth of that floor (seed 0, 400 epochs of 4 batches each).
#[test]
fn a_residual_learns_the_term_the_white_box_model_lacks() {
    let truth = sprung_double_pendulum(200.0);
    let sim = |seed| {
        let cfg = SimConfig {
            count: 256,
            seed,
            q_range: 1.5,
            qdot_range: 3.0,
            u_std: 30.0,
            ..SimConfig::default()
        };
        simulate(&truth, truth.defaults(), &cfg).unwrap()
    };
    let (data, val) = (sim(1), sim(2));
    let cfg = TrainConfig {
        epochs: 400,
        batch_size: 64,
        lr: 3e-3,
        seed: 0,
        ..TrainConfig::default()
    };
    let dp = Some(Template::DoublePendulum);
    let white_box = best_val(
        ModelSpec::named("W-B", dp.clone()).unwrap(),
        &data,
        &val,
        cfg.clone(),
    );
    let with = |part: &str| {
        let mut spec = json!({"mass": "template", "potential": "template", "forces": "template"});
        spec[part] = json!({"type": "template", "residual": {"type": "mlp", "hidden": [32, 32]}});
        best_val(
            ModelSpec::parse(&spec.to_string(), dp.clone()).unwrap(),
            &data,
            &val,
            cfg.clone(),
        )
    };
    let (potential, forces) = (with("potential"), with("forces"));
    eprintln!(
        "best validation loss: W-B {white_box:.3e}, +V residual {potential:.3e}, +F residual {forces:.3e}"
    );
    assert!(
        potential < 0.1 * white_box,
        "residual potential {potential:e} vs W-B {white_box:e}"
    );
    assert!(
        forces < 0.1 * white_box,
        "residual force {forces:e} vs W-B {white_box:e}"
    );
}

/// A residual's network starts at zero output: before any training, the model is exactly
/// its physics (same one-step predictions as plain W-B, bit for bit in f32).
#[test]
fn a_residual_starts_at_the_physics_model() {
    let t = Template::DoublePendulum;
    let data = simulate(
        &t,
        t.defaults(),
        &SimConfig {
            count: 32,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let cfg = TrainConfig {
        epochs: 1,
        val_fraction: 0.0,
        ..TrainConfig::default()
    };
    let spec = r#"{"mass": "template",
        "potential": {"type": "template", "residual": "mlp"},
        "forces": {"type": "template", "residual": {"type": "mlp", "hidden": [8]}}}"#;
    let predict = |spec: ModelSpec| {
        let tr = Trainer::new("t", spec, &[], &data, None, cfg.clone(), &flex()).unwrap();
        let e = graybox::infer::Evaluator::from_file(&tr.model_file()).unwrap();
        e.predict(
            &[0.3, -0.2, 1.0, 0.5, 1.1, 0.0, -2.0, 3.0],
            &[3.0, -2.0, 0.0, 40.0],
            true,
        )
    };
    let plain = predict(ModelSpec::named("W-B", Some(t.clone())).unwrap());
    let residual = predict(ModelSpec::parse(spec, Some(t.clone())).unwrap());
    assert_eq!(plain, residual);
}

/// `q` wrapped to (−π, π], as a sensor reports an angle.
fn wrap(v: &mut [f64]) {
    for x in v {
        *x = (*x + PI).rem_euclid(2.0 * PI) - PI;
    }
}

/// The paper's double pendulum (q over a whole turn) with the angles wrapped: the next angle
/// jumps by 2π wherever it crosses ±π. MVF with `periodic: [true, true]` on the
/// wrapped data reaches a best validation loss within 20% of plain MVF on the same data
/// unwrapped (seed 0, 300 epochs of 4 batches each).
#[test]
fn wrapped_angles_train_as_well_as_unwrapped_ones_when_periodic() {
    let t = Template::DoublePendulum;
    let sim = |seed| {
        let cfg = SimConfig {
            count: 256,
            seed,
            ..SimConfig::default()
        };
        simulate(&t, t.defaults(), &cfg).unwrap()
    };
    let (data, val) = (sim(1), sim(2));
    let wrapped = |d: &Dataset| {
        let mut w = d.clone();
        wrap(&mut w.q);
        wrap(&mut w.q_next);
        w
    };
    let jumps = |d: &Dataset| {
        d.q.iter()
            .zip(&d.q_next)
            .filter(|(a, b)| (*a - *b).abs() > PI)
            .count()
    };
    let (wdata, wval) = (wrapped(&data), wrapped(&val));
    assert!(
        jumps(&wdata) > 0 && jumps(&data) == 0,
        "the test needs jumps in the wrapped data"
    );
    let cfg = TrainConfig {
        epochs: 300,
        batch_size: 64,
        seed: 0,
        ..TrainConfig::default()
    };
    let mvf = || ModelSpec::named("MVF", Some(t.clone())).unwrap();
    let unwrapped = best_val(mvf(), &data, &val, cfg.clone());
    let periodic = best_val(
        mvf(),
        &wdata,
        &wval,
        TrainConfig {
            periodic: vec![true, true],
            ..cfg.clone()
        },
    );
    eprintln!(
        "best validation loss: MVF unwrapped {unwrapped:.3e}, MVF periodic on wrapped {periodic:.3e}"
    );
    assert!(
        periodic <= 1.2 * unwrapped,
        "periodic on wrapped {periodic:e} vs unwrapped {unwrapped:e}"
    );
}

/// `graybox model` of a template with angles (a URDF's continuous joints) keeps them
/// periodic: its file used to say none, so a transition whose q₁ wraps from π − ε to −π + ε
/// cost (2π)² instead of what the same transition costs unwrapped (rounding only: the model
/// is the true system, so both losses are the integrator's agreement with itself, ~1e-12).
#[test]
fn a_template_model_keeps_its_angles_periodic() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/urdf/double_pendulum.urdf"
    );
    let t = Template::Urdf(Arc::new(
        UrdfTemplate::from_urdf(&std::fs::read_to_string(path).unwrap()).unwrap(),
    ));
    let (dt, values) = (0.01, t.defaults());
    let made = ModelFile::from_template(&t, &values, dt, Integrator::Rk4).unwrap();
    let file = ModelFile::from_bytes(&made.to_bytes().unwrap()).unwrap();
    assert_eq!(file.config.space.periodic(), [true, true]);

    // q₁ just below π moving up: the next q₁ is just above π, which a logger writes as −π + ε.
    let x = [PI - 0.005, 0.3, 2.0, -1.0];
    let u = [0.0, 0.0];
    let next = true_step(
        &TemplateSystem::new(t.clone(), values),
        &x,
        &u,
        dt,
        Integrator::Rk4,
    );
    assert!(next[0] > PI, "the step crosses π: {next:?}");
    let row = |q1_next: f64| {
        Dataset::new(
            dt,
            (2, 2),
            2,
            [
                x[..2].to_vec(),
                x[2..].to_vec(),
                u.to_vec(),
                vec![q1_next, next[1]],
                next[2..].to_vec(),
            ],
        )
        .unwrap()
    };
    let model = Model::from_file(&file, &flex()).unwrap();
    let unwrapped = evaluate(&model, &row(next[0])).unwrap();
    let wrapped = evaluate(&model, &row(next[0] - 2.0 * PI)).unwrap();
    // f32 evaluation of the true system's own step: both are rounding-sized; unwrapped as an
    // ordinary coordinate the wrapped row would cost (2π)² ≈ 39.
    assert!(unwrapped < 1e-6, "{unwrapped}");
    assert!(wrapped < 1e-6, "wrapped across π: {wrapped}");
}

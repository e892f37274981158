//! The training step against what Burn's op-by-op graph computed before it was retired
//! (tests/fixtures/gradients, README there), shared by the f64 and the f32 test binaries:
//! the one-step loss and every parameter tensor's gradient for structured models of every
//! component kind, residual networks on a template's V and F, a periodic model, the naive
//! network, n = 2, 3 and 6, and each integrator; and a training run's best validation loss.

use std::path::Path;

use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use super::{PAPER, config, perturb, random_loss_and_gradients};
use graybox::data::Dataset;
use graybox::model::Model;
use graybox::model::params_io::{NamedArray, import};
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::space::Space;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use graybox::train::{TrainConfig, Trainer};

/// ‖a − b‖ / ‖b‖ (0 when both are zero).
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    let d = norm(&mut a.iter().zip(b).map(|(x, y)| x - y));
    let s = norm(&mut b.iter().copied());
    if s == 0.0 { d } else { d / s }
}

/// The cases: structured models of every component kind, residual networks on a template's V
/// and F, a periodic model, the naive network, n = 2, 3 and 6, and each integrator.
fn cases() -> Vec<(&'static str, ModelSpec, usize, usize, Integrator, bool)> {
    let dp = Some(Template::DoublePendulum);
    let custom = r#"{"kind":"structured","mass":{"type":"constant"},"potential":{"type":"quadratic"},"forces":{"type":"constant_affine"}}"#;
    let residual = r#"{"mass": "template",
        "potential": {"type": "template", "residual": {"type": "mlp", "hidden": [16, 16]}},
        "forces": {"type": "template", "residual": "mlp"}}"#;
    vec![
        (
            "MVF",
            ModelSpec::named("MVF", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MVF n=3",
            ModelSpec::named("MVF", None).unwrap(),
            3,
            1,
            Integrator::Midpoint,
            false,
        ),
        (
            "MVF n=6",
            ModelSpec::named("MVF", None).unwrap(),
            6,
            2,
            Integrator::Euler,
            false,
        ),
        (
            "MVB",
            ModelSpec::named("MVB", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MV",
            ModelSpec::named("MV", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "W-B",
            ModelSpec::named("W-B", dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "constant",
            serde_json::from_str(custom).unwrap(),
            3,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "residuals",
            ModelSpec::parse(residual, dp.clone()).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
        (
            "MVF periodic",
            ModelSpec::named("MVF", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            true,
        ),
        (
            "passive",
            ModelSpec::parse(
                r#"{"mass": "mlp", "potential": "mlp", "forces": "passive"}"#,
                None,
            )
            .unwrap(),
            2,
            1,
            Integrator::Rk4,
            false,
        ),
        (
            "naive",
            ModelSpec::named("naive", None).unwrap(),
            2,
            2,
            Integrator::Rk4,
            false,
        ),
    ]
}

/// Each case's model at perturbed parameters (seeded: the same on every call).
fn case_models(dev: &Device) -> Vec<(&'static str, Model)> {
    cases()
        .into_iter()
        .map(|(what, spec, n, m, integrator, periodic)| {
            let mut c = config(spec, n, m);
            c.integrator = integrator;
            if periodic {
                c.space = Space::flat(n, &[true]);
            }
            let model = Model::init(c, None, 5, dev).unwrap();
            (what, perturb(&model, dev))
        })
        .collect()
}

/// What Burn's op-by-op graph computed for one case: the parameters it ran at, the one-step
/// loss on `random_loss_and_gradients`' rows, and each parameter tensor's gradient.
#[derive(Serialize, Deserialize)]
pub struct Recorded {
    pub case: String,
    pub params: Vec<NamedArray>,
    pub loss: f64,
    pub gradients: Vec<Vec<f64>>,
}

/// Rows per loss: blocks of the tape are independent, so one (partial) block of 17 covers the
/// math.
const ROWS: usize = 17;

/// The step's one-step loss and every parameter tensor's gradient against the graph's as
/// `path` recorded them, at the parameters it ran at, to `tol` relative (per tensor), on
/// autodiff device `dev`.
pub fn step_matches_graph(dev: &Device, tol: f64, path: &Path) {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e} (tests/fixtures/gradients)", path.display()));
    let records: Vec<Recorded> = serde_json::from_str(&text).unwrap();
    let models = case_models(dev);
    assert_eq!(records.len(), models.len(), "one record per case");
    for ((what, model), rec) in models.into_iter().zip(&records) {
        assert_eq!(what, rec.case);
        let params = import(model.params.clone(), &rec.params, dev).unwrap();
        let model = Model::from_parts(model.config.clone(), params, dev);
        let (v, g) = random_loss_and_gradients(&model, dev, ROWS);
        assert!(
            (v - rec.loss).abs() <= tol * rec.loss.abs(),
            "{what}: loss {v} vs recorded {}",
            rec.loss
        );
        assert_eq!(g.len(), rec.gradients.len(), "{what}: parameter tensors");
        for (i, (a, b)) in g.iter().zip(&rec.gradients).enumerate() {
            let e = relative(a, b);
            assert!(e <= tol, "{what}: tensor {i}: gradient error {e:e}");
        }
        eprintln!("{what}: loss {v:e} matches");
    }
}

/// The paper's double pendulum data: `count` transitions from seed `seed`.
fn paper_data(count: usize, seed: u64) -> Dataset {
    let config = SimConfig {
        count,
        seed,
        ..SimConfig::default()
    };
    simulate(&Template::DoublePendulum, PAPER.to_vec(), &config).unwrap()
}

/// The best validation loss of `epochs` epochs of `name` (MVF, or W-B on the double
/// pendulum template from wrong physical values: started at the paper's, it would have
/// nothing to learn; seed `seed`) on 512 of the paper's double pendulum transitions,
/// validated on 256.
pub fn best_val_loss(name: &str, seed: u64, epochs: usize, dev: &Device) -> f64 {
    let (train, val) = (paper_data(512, 1), paper_data(256, 2));
    let cfg = TrainConfig {
        epochs,
        seed,
        ..TrainConfig::default()
    };
    let template = (name != "MVF").then_some(Template::DoublePendulum);
    let init = match &template {
        Some(_) => vec![("m1".to_string(), 13.0), ("l2".to_string(), 0.8)],
        None => vec![],
    };
    let spec = ModelSpec::named(name, template).unwrap();
    let mut trainer = Trainer::new(name, spec, &init, &train, Some(&val), cfg, dev).unwrap();
    trainer.run(&Default::default(), |_, _| {}).unwrap();
    trainer.report().best_val_loss.unwrap()
}

/// The models whose training trajectories are recorded.
pub const TRAINED: [&str; 2] = ["MVF", "W-B"];

/// One recorded training run of Burn's graph: 300 epochs of `best_val_loss`.
#[derive(Serialize, Deserialize)]
pub struct RecordedRun {
    pub model: String,
    pub seed: u64,
    pub epochs: usize,
    pub best_val_loss: f64,
}

/// The recorded graph runs of `model`.
pub fn recorded_runs(path: &Path, model: &str) -> Vec<RecordedRun> {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e} (tests/fixtures/gradients)", path.display()));
    let runs: Vec<RecordedRun> = serde_json::from_str(&text).unwrap();
    runs.into_iter().filter(|r| r.model == model).collect()
}

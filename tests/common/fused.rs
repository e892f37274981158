//! The fused step (`Model::fused`) against Burn's op-by-op graph (`Model::graph`), shared by
//! the f64 and the f32 test binaries: the one-step loss and every parameter tensor's
//! gradient for structured models of every component kind, residual networks on a
//! template's V and F, a periodic model, the naive network, n = 2, 3 and 6, and each
//! integrator; and a training run's best validation loss on either path.

use burn::tensor::Device;

use super::{PAPER, config, perturb, random_loss_and_gradients};
use graybox::data::Dataset;
use graybox::model::Model;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
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

/// The fused step's one-step loss and every parameter tensor's gradient against Burn's graph
/// on the same parameters, to `tol` relative (per tensor), on autodiff device `dev`.
pub fn fused_matches_graph(dev: &Device, tol: f64) {
    let dev = dev.clone();
    let dp = Some(Template::DoublePendulum);
    let custom = r#"{"kind":"structured","mass":{"type":"constant"},"potential":{"type":"quadratic"},"forces":{"type":"constant_affine"}}"#;
    let residual = r#"{"mass": "template",
        "potential": {"type": "template", "residual": {"type": "mlp", "hidden": [16, 16]}},
        "forces": {"type": "template", "residual": "mlp"}}"#;
    let cases: Vec<(&str, ModelSpec, usize, usize, Integrator, bool)> = vec![
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
    ];
    for (what, spec, n, m, integrator, periodic) in cases {
        let mut c = config(spec, n, m);
        c.integrator = integrator;
        if periodic {
            c.periodic = (0..n).map(|k| k == 0).collect();
        }
        let burn = perturb(&Model::init(c, None, 5, &dev).unwrap(), &dev).graph();
        let fused = burn.clone().fused();
        // 17 rows: blocks of the tape are independent, so one (partial) block covers the math.
        let (v_ref, g_ref) = random_loss_and_gradients(&burn, &dev, 17);
        let (v, g) = random_loss_and_gradients(&fused, &dev, 17);
        assert!(
            (v - v_ref).abs() <= tol * v_ref.abs(),
            "{what}: loss {v} vs {v_ref}"
        );
        for (i, (a, b)) in g.iter().zip(&g_ref).enumerate() {
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

/// The best validation loss of `epochs` epochs of MVF (seed `seed`) on 512 of the paper's
/// double pendulum transitions, validated on 256, through Burn's graph when `graph`, else
/// through the fused step.
pub fn best_val_loss(graph: bool, seed: u64, epochs: usize, dev: &Device) -> f64 {
    let (train, val) = (paper_data(512, 1), paper_data(256, 2));
    let cfg = TrainConfig {
        epochs,
        seed,
        ..TrainConfig::default()
    };
    let spec = ModelSpec::named("MVF", None).unwrap();
    let trainer = Trainer::new("MVF", spec, &[], &train, Some(&val), cfg, dev).unwrap();
    let mut trainer = if graph { trainer.on_graph() } else { trainer };
    trainer.run(&Default::default(), |_, _| {}).unwrap();
    trainer.report().best_val_loss.unwrap()
}

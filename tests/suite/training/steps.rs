//! Transitions of their own Δt (a log kept on its samples' times): the white-box pendulum
//! trained on trajectories sampled with ±5 % jitter, each transition carrying its step,
//! identifies the parameters a uniformly sampled recording of the same system gives, within
//! the seeds' spread; the same jittered data with its steps dropped (trained as if uniform)
//! fits far worse, so the steps are what the loss integrated over.

use std::sync::atomic::AtomicBool;

use graybox::data::Dataset;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::model::spec::ModelSpec;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::train::{TrainConfig, Trainer};

use super::flex;

/// The pendulum the data comes from: m, l, g, b (input gain), eta (damping), away from the
/// template's defaults that training starts from.
const TRUTH: [f64; 5] = [1.0, 1.0, 9.0, 0.8, -0.3];
const H: f64 = 0.05;

/// 16 trajectories of 40 transitions: transition k lasts H(1 + jitter·r), r uniform in
/// [−1, 1], under a held input; each from the truth by 20 RK4 substeps (error ~1e-10).
fn recording(jitter: f64, seed: u64) -> Dataset {
    let t = Template::Pendulum;
    let file = ModelFile::from_template(&t, &TRUTH, H, Integrator::Rk4).unwrap();
    let truth = Evaluator::from_file(&file).unwrap();
    let mut rng = Rng::derive(seed, 7);
    let mut arrays: [Vec<f64>; 5] = Default::default();
    let (mut steps, mut lengths) = (vec![], vec![]);
    for _ in 0..16 {
        let mut x = vec![rng.uniform_in(-1.5, 1.5), rng.uniform_in(-1.0, 1.0)];
        for _ in 0..40 {
            let u = vec![rng.uniform_in(-1.0, 1.0)];
            let dt = H * (1.0 + jitter * rng.uniform_in(-1.0, 1.0));
            let mut next = x.clone();
            truth.rollout(
                &x,
                (20, dt / 20.0),
                |_, _| u.clone(),
                |y, _| {
                    next = y.to_vec();
                    true
                },
            );
            for (a, v) in arrays.iter_mut().zip([x[0], x[1], u[0], next[0], next[1]]) {
                a.push(v);
            }
            steps.push(dt);
            x = next;
        }
        lengths.push(40);
    }
    let data = Dataset::new(H, (1, 1), 1, arrays).unwrap();
    data.with_trajectories(lengths)
        .unwrap()
        .with_steps(steps)
        .unwrap()
}

/// g/l, b/(m l²), eta/(m l²) and the last validation loss of the white-box pendulum trained on
/// `data` from `seed`.
fn identified(data: &Dataset, seed: u64) -> ([f64; 3], f64) {
    let spec = ModelSpec::named("W-B", Some(Template::Pendulum)).unwrap();
    let cfg = TrainConfig {
        epochs: 60,
        batch_size: 32,
        lr: 0.02,
        seed,
        ..TrainConfig::default()
    };
    let mut t = Trainer::new("W-B", spec, &[], data, None, cfg, &flex()).unwrap();
    let mut last = f64::NAN;
    t.run(&AtomicBool::new(false), |m, _| last = m.val_loss.unwrap())
        .unwrap();
    let v: Vec<f64> = (t.model().physical_values().unwrap())
        .into_iter()
        .map(|(_, v)| v)
        .collect();
    let ml2 = v[0] * v[1] * v[1];
    ([v[2] / v[1], v[3] / ml2, v[4] / ml2], last)
}

#[test]
fn a_jittered_recording_trains_without_resampling_as_a_uniform_one() {
    let jittered = recording(0.05, 1);
    assert!(jittered.steps.is_some());
    let mut ignored = jittered.clone();
    ignored.steps = None;
    let uniform = recording(0.0, 1);
    assert!(uniform.steps.is_none());
    let want = [TRUTH[2] / TRUTH[1], TRUTH[3], TRUTH[4]];
    let mut by_data = vec![];
    for (name, data) in [
        ("uniform", &uniform),
        ("jittered", &jittered),
        ("ignored", &ignored),
    ] {
        let runs: Vec<([f64; 3], f64)> = (1..=2).map(|s| identified(data, s)).collect();
        eprintln!("{name}: {runs:?} (truth {want:?})");
        by_data.push(runs);
    }
    let (uniform, jittered, ignored) = (&by_data[0], &by_data[1], &by_data[2]);
    for (i, want) in want.iter().enumerate() {
        // The seeds' spread of each combination on uniform data, and at least 1 % of its
        // size: Adam's last steps move a white-box parameter by about lr · 1e-2.
        let spread = (uniform[0].0[i] - uniform[1].0[i])
            .abs()
            .max(0.01 * want.abs());
        let mean = |r: &[([f64; 3], f64)]| 0.5 * (r[0].0[i] + r[1].0[i]);
        assert!(
            (mean(jittered) - mean(uniform)).abs() <= 2.0 * spread,
            "combination {i}: jittered {jittered:?}, uniform {uniform:?}"
        );
        assert!((mean(uniform) - want).abs() <= 2.0 * spread, "{uniform:?}");
    }
    // Dropping the steps leaves a 5 % error in each transition's length: its loss stays far
    // above the timed data's, which the model class fits to its rounding.
    let loss = |r: &[([f64; 3], f64)]| r.iter().map(|r| r.1).fold(0.0, f64::max);
    assert!(
        loss(ignored) > 10.0 * loss(jittered),
        "ignored {ignored:?}, jittered {jittered:?}"
    );
}

//! Multi-step (shooting) training: windows of H transitions of the data's trajectories, the
//! model's own rollout through them, H = 1 unchanged.

use std::sync::atomic::AtomicBool;

use burn::tensor::Device;
use graybox::backend::{Backend, Precision, device};
use graybox::data::Dataset;
use graybox::infer::Evaluator;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, double_pendulum_trajectories};
use graybox::train::windows::{self, Windows};
use graybox::train::{TrainConfig, TrainState, Trainer};

fn flex() -> Device {
    device(Backend::Flex, Precision::F32).unwrap().autodiff()
}

fn trajectories(count: usize, steps: usize, seed: u64) -> Dataset {
    double_pendulum_trajectories(count, steps, seed).unwrap()
}

fn config(horizon: usize, epochs: usize) -> TrainConfig {
    TrainConfig {
        epochs,
        batch_size: 32,
        horizon,
        discount: 0.9,
        ..TrainConfig::default()
    }
}

fn mvf() -> ModelSpec {
    ModelSpec::named("MVF", Some(Template::DoublePendulum)).unwrap()
}

/// A window's loss is the discounted mean of its steps' errors along the model's own rollout:
/// checked against the f64 evaluator (an independent implementation of the same model)
/// rolling out from the window's first state.
#[test]
fn a_window_loss_is_the_discounted_error_of_the_models_own_rollout() {
    let data = trajectories(2, 12, 1);
    let cfg = TrainConfig {
        val_fraction: 0.0,
        ..config(4, 1)
    };
    let trainer = Trainer::new("MVF", mvf(), &[], &data, None, cfg, &flex()).unwrap();
    let eval = Evaluator::from_file(&trainer.model_file()).unwrap();
    let start = 13; // row 1 of the second trajectory
    let (loss, grads) = trainer.loss_and_grads(&[start]);
    assert!(grads.iter().any(Option::is_some));

    let n = 2;
    let row = |a: &[f64], i: usize| a[i * n..(i + 1) * n].to_vec();
    let x0 = [row(&data.q, start), row(&data.qdot, start)].concat();
    let mut states = vec![];
    let u = |k: usize, _: &[f64]| data.u[(start + k) * 2..(start + k + 1) * 2].to_vec();
    eval.rollout(&x0, (4, eval.config.dt), u, |x, _| {
        states.push(x.to_vec());
        true
    });
    let weights = windows::weights(4, 0.9);
    let expect: f64 = (0..4)
        .map(|k| {
            let (q, qd) = (
                row(&data.q_next, start + k),
                row(&data.qdot_next, start + k),
            );
            // Both coordinates are angles: 2(1 − cos Δq); velocities squared (λ = 1).
            let e: f64 = (0..n)
                .map(|i| {
                    2.0 * (1.0 - (states[k][i] - q[i]).cos()) + (states[k][n + i] - qd[i]).powi(2)
                })
                .sum();
            weights[k] * e
        })
        .sum();
    // f32 training against the f64 evaluator over four RK4 steps: agreement to ~1e-5
    // relative; 1e-3 leaves room for the networks' f32 rounding, far below what a missing or
    // misweighted step would change (each step is a sizable share of the total).
    assert!(
        (loss - expect).abs() <= 1e-3 * expect,
        "loss {loss} against the f64 rollout's {expect}"
    );
}

#[test]
fn windows_come_from_uploaded_boundaries_even_where_rows_chain() {
    // Two trajectories of 3 whose junction chains bit for bit (the second starts where the
    // first ended): uploaded as two, no window may span them.
    let whole = trajectories(1, 6, 2);
    let split = whole.clone().with_trajectories(vec![3, 3]).unwrap();
    assert_eq!(Windows::of(&whole, 2, 1.0).starts, [0, 1, 2, 3, 4]);
    assert_eq!(Windows::of(&split, 2, 1.0).starts, [0, 1, 3, 4]);
    assert_eq!(Windows::of(&split, 3, 1.0).starts, [0, 3]);
    let err = windows::check(&split, 4).unwrap_err().to_string();
    assert!(
        err.contains("training.horizon") && err.contains("longest in the training data is 3"),
        "{err}"
    );
}

/// A multi-step run's validation split keeps trajectories whole, so its validation set has
/// windows and reports their loss beside the one-step loss, and a run without chains is
/// refused naming the horizon.
#[test]
fn a_multi_step_run_validates_on_whole_trajectories() {
    let data = trajectories(5, 20, 3);
    let mut t = Trainer::new("MVF", mvf(), &[], &data, None, config(5, 1), &flex()).unwrap();
    let m = t.run_epoch(&AtomicBool::new(false)).unwrap();
    let (one, h) = (m.val_loss.unwrap(), m.val_horizon_loss.unwrap());
    assert!(
        one.is_finite() && h.is_finite() && h > one,
        "one-step {one}, 5-step {h}"
    );
    // One trajectory of 5 goes to validation (round(0.2 × 100) = 20 transitions): the
    // training set keeps 4 × 16 windows.
    let state = t.checkpoint();
    assert_eq!(state.samples_seen, 4 * 16 * 5);

    let flat = graybox::sim::simulate(
        &Template::DoublePendulum,
        Template::DoublePendulum.defaults(),
        &SimConfig {
            count: 64,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let err = Trainer::new("MVF", mvf(), &[], &flat, None, config(5, 1), &flex())
        .err()
        .expect("no chains of 5")
        .to_string();
    assert!(
        err.contains("training.horizon") && err.contains("longest in the training data is 1"),
        "{err}"
    );
}

/// H = 1 is the one-step loss whatever the trajectories: a trajectory dataset trains exactly
/// as its flat rows do, and the configuration writes no new field into files.
#[test]
fn horizon_one_trains_exactly_as_before() {
    let data = trajectories(3, 20, 4);
    let mut flat = data.clone();
    flat.trajectories = None;
    let never = AtomicBool::new(false);
    let run = |d: &Dataset| {
        let mut t = Trainer::new("MVF", mvf(), &[], d, None, config(1, 2), &flex()).unwrap();
        t.run(&never, |_, _| {}).unwrap();
        t.checkpoint()
    };
    let (a, b) = (run(&data), run(&flat));
    assert_eq!(a.params, b.params);
    let losses = |s: &TrainState| {
        s.history
            .iter()
            .map(|m| (m.train_loss, m.val_loss))
            .collect::<Vec<_>>()
    };
    assert_eq!(losses(&a), losses(&b));
    let cfg = serde_json::to_value(TrainConfig::default()).unwrap();
    assert!(
        cfg.get("horizon").is_none() && cfg.get("discount").is_none(),
        "{cfg}"
    );
}

/// A multi-step run resumed from a checkpoint equals the uninterrupted run bit for bit.
#[test]
fn a_resumed_multi_step_run_equals_an_uninterrupted_one() {
    let data = trajectories(4, 15, 5);
    let never = AtomicBool::new(false);
    let mut full = Trainer::new("MVF", mvf(), &[], &data, None, config(3, 4), &flex()).unwrap();
    full.run(&never, |_, _| {}).unwrap();
    let mut first = Trainer::new("MVF", mvf(), &[], &data, None, config(3, 4), &flex()).unwrap();
    for _ in 0..2 {
        first.run_epoch(&never).unwrap();
    }
    let bytes = first.checkpoint().to_bytes();
    drop(first);
    let state = TrainState::from_bytes(&bytes).unwrap();
    assert_eq!(state.train.horizon, 3);
    let mut resumed = Trainer::resume(state, &data, None, &flex()).unwrap();
    resumed.run(&never, |_, _| {}).unwrap();
    assert_eq!(full.checkpoint().params, resumed.checkpoint().params);
    assert_eq!(full.checkpoint().history.len(), 4);
    let h = |t: &Trainer| {
        t.checkpoint()
            .history
            .iter()
            .map(|m| m.val_horizon_loss)
            .collect::<Vec<_>>()
    };
    assert_eq!(h(&full), h(&resumed));
}

/// A curriculum's one-step epochs train exactly as an H = 1 run (every row a window, the same
/// shuffles), the windows of its horizon take over after them, and a run resumed inside the
/// one-step epochs equals the uninterrupted one.
#[test]
fn one_step_epochs_train_on_rows_then_on_windows() {
    let data = trajectories(4, 15, 6);
    let never = AtomicBool::new(false);
    let cfg = |horizon, one_step_epochs, epochs| TrainConfig {
        val_fraction: 0.0,
        one_step_epochs,
        ..config(horizon, epochs)
    };
    let new = |c| Trainer::new("MVF", mvf(), &[], &data, None, c, &flex()).unwrap();
    let mut one_step = new(cfg(1, 0, 2));
    one_step.run(&never, |_, _| {}).unwrap();
    let mut curriculum = new(cfg(3, 2, 3));
    curriculum.run_epoch(&never).unwrap();
    let bytes = curriculum.checkpoint().to_bytes();
    curriculum.run_epoch(&never).unwrap();
    assert_eq!(one_step.checkpoint().params, curriculum.checkpoint().params);
    let rows = data.count() as u64;
    assert_eq!(curriculum.checkpoint().samples_seen, 2 * rows);
    curriculum.run_epoch(&never).unwrap();
    // 4 trajectories of 15 transitions hold 13 windows of 3 each.
    let seen = curriculum.checkpoint().samples_seen;
    assert_eq!(seen, 2 * rows + 4 * 13 * 3);
    // The window epochs start Adam afresh: its step count is the window epoch's batches only.
    assert_eq!(curriculum.checkpoint().adam.step, (4 * 13_u64).div_ceil(32));

    let state = TrainState::from_bytes(&bytes).unwrap();
    let mut resumed = Trainer::resume(state, &data, None, &flex()).unwrap();
    resumed.run(&never, |_, _| {}).unwrap();
    assert_eq!(curriculum.checkpoint().params, resumed.checkpoint().params);

    let err = TrainConfig {
        one_step_epochs: 3,
        ..cfg(3, 0, 3)
    }
    .validate()
    .unwrap_err();
    assert!(
        err.to_string().contains("training.one_step_epochs"),
        "{err}"
    );
}

/// `window_lr` sets the window epochs' learning rate only: equal to `lr` it changes no bit,
/// and another value leaves the one-step epochs as they were and changes the window epochs.
#[test]
fn window_lr_applies_to_the_window_epochs_only() {
    let data = trajectories(4, 15, 6);
    let never = AtomicBool::new(false);
    // Of a run of 2 one-step epochs and 1 on windows of 3, the parameters after `epochs`.
    let run = |window_lr: Option<f64>, epochs: usize| {
        let cfg = TrainConfig {
            val_fraction: 0.0,
            one_step_epochs: 2,
            window_lr,
            ..config(3, 3)
        };
        let mut t = Trainer::new("MVF", mvf(), &[], &data, None, cfg, &flex()).unwrap();
        for _ in 0..epochs {
            t.run_epoch(&never).unwrap();
        }
        t.checkpoint().params
    };
    let lr = TrainConfig::default().lr;
    assert_eq!(run(None, 3), run(Some(lr), 3));
    assert_eq!(
        run(None, 2),
        run(Some(lr / 10.0), 2),
        "one-step epochs use lr"
    );
    assert_ne!(
        run(None, 3),
        run(Some(lr / 10.0), 3),
        "window epochs use window_lr"
    );
    let err = TrainConfig {
        window_lr: Some(0.0),
        ..config(3, 3)
    }
    .validate()
    .unwrap_err();
    assert!(err.to_string().contains("training.window_lr"), "{err}");
}

/// The error-against-horizon figures (all window starts stepped as one batch, starts leaving
/// as their trajectory ends) are each window's own rollout: checked against one
/// `Evaluator::rollout` per window start.
#[test]
fn horizon_errors_are_each_windows_own_rollout() {
    use graybox::infer::horizons::{check_horizons, horizon_errors};
    let data = trajectories(3, 12, 6);
    let cfg = TrainConfig {
        val_fraction: 0.0,
        ..config(1, 1)
    };
    let mut t = Trainer::new("MVF", mvf(), &[], &data, None, cfg, &flex()).unwrap();
    t.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let e = Evaluator::from_file(&t.model_file()).unwrap();
    let horizons = check_horizons(&[10, 1, 4, 10], 100).unwrap();
    assert_eq!(horizons, [1, 4, 10]);
    let found = horizon_errors(&e, &data, &horizons, &|| false).unwrap();
    for (h, f) in horizons.iter().zip(&found) {
        // Starts with h transitions left in their trajectory of 12.
        assert_eq!(f.windows, 3 * (12 - h + 1), "h {h}");
        let mut pos = vec![];
        for traj in 0..3 {
            for i in 0..=(12 - h) {
                let r = traj * 12 + i;
                let x0 = [&data.q[2 * r..2 * r + 2], &data.qdot[2 * r..2 * r + 2]].concat();
                let mut last = vec![];
                e.rollout(
                    &x0,
                    (*h, e.config.dt),
                    |k, _| data.u[2 * (r + k)..2 * (r + k) + 2].to_vec(),
                    |x, _| {
                        last = x.to_vec();
                        true
                    },
                );
                let end = r + h - 1;
                let wrap = |d: f64| d.sin().atan2(d.cos());
                let d: f64 = (0..2)
                    .map(|j| wrap(last[j] - data.q_next[2 * end + j]).powi(2))
                    .sum();
                pos.push(d.sqrt());
            }
        }
        pos.sort_by(f64::total_cmp);
        let k = pos.len();
        let median = if k % 2 == 1 {
            pos[k / 2]
        } else {
            0.5 * (pos[k / 2 - 1] + pos[k / 2])
        };
        let mean = pos.iter().sum::<f64>() / k as f64;
        // Both f64; the batch steps through SIMD columns, the single rollout through scalars:
        // rounding differs in the last bits only.
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-12);
        assert!(
            close(f.position_median.unwrap(), median),
            "h {h}: {f:?} vs {median}"
        );
        assert!(
            close(f.position_mean.unwrap(), mean),
            "h {h}: {f:?} vs {mean}"
        );
        assert!((f.seconds - *h as f64 * 0.01).abs() < 1e-12);
    }
    assert!(check_horizons(&[], 10).is_err() && check_horizons(&[0], 10).is_err());
    assert!(check_horizons(&[11], 10).is_err());
}

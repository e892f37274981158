//! Training behaviour in f32 (the default precision): every parameterization trains and
//! evaluates, backends agree, resume equals an uninterrupted run, failures are reported.

use crate::common;
#[path = "training/delay.rs"]
mod delay;
#[path = "training/ensemble.rs"]
mod ensemble;
#[path = "training/fused.rs"]
mod fused;
#[path = "training/steps.rs"]
mod steps;
#[path = "training/torque.rs"]
mod torque;

use std::sync::atomic::AtomicBool;

use burn::tensor::Device;
use graybox::backend::{Backend, Precision, device};
use graybox::data::Dataset;
use graybox::error::Error;
use graybox::model::Model;
use graybox::model::file::ModelFile;
use graybox::model::spec::{ModelSpec, NAMED};
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};
use graybox::train::trainer::evaluate;
use graybox::train::{TrainConfig, TrainState, Trainer};

fn flex() -> Device {
    device(Backend::Flex, Precision::F32).unwrap().autodiff()
}

fn data(t: &Template, count: usize, seed: u64) -> Dataset {
    simulate(
        t,
        t.defaults(),
        &SimConfig {
            count,
            seed,
            ..SimConfig::default()
        },
    )
    .unwrap()
}

fn quick(epochs: usize) -> TrainConfig {
    TrainConfig {
        epochs,
        batch_size: 32,
        ..TrainConfig::default()
    }
}

#[test]
fn every_named_model_trains_and_evaluates() {
    for t in [Template::DoublePendulum, Template::Cartpole] {
        let train = data(&t, 64, 1);
        let val = data(&t, 32, 2);
        for name in NAMED {
            let spec = ModelSpec::named(name, Some(t.clone())).unwrap();
            let mut trainer =
                Trainer::new(name, spec, &[], &train, Some(&val), quick(1), &flex()).unwrap();
            let m = trainer.run_epoch(&AtomicBool::new(false)).unwrap();
            assert!(
                m.train_loss.is_finite() && m.val_loss.unwrap().is_finite(),
                "{name} on {}",
                t.name()
            );
            let file = trainer.model_file();
            let back = ModelFile::from_bytes(&file.to_bytes().unwrap()).unwrap();
            let model =
                Model::from_file(&back, &device(Backend::Flex, Precision::F32).unwrap()).unwrap();
            let loss = evaluate(&model, &val).unwrap();
            assert!(loss.is_finite(), "{name}");
        }
    }
}

#[test]
fn white_box_parts_need_a_template() {
    for name in NAMED
        .iter()
        .filter(|n| **n != "MVF" && **n != "naive" && **n != "MVB")
    {
        let err = ModelSpec::named(name, None).unwrap_err();
        assert!(
            matches!(&err, Error::Invalid { field, .. } if field == "template"),
            "{name}: {err}"
        );
    }
    let json = r#"{"kind":"structured","mass":{"type":"template"},"potential":{"type":"mlp"},"forces":{"type":"mlp"}}"#;
    let err = ModelSpec::parse(json, None).unwrap_err();
    assert!(err.to_string().contains("mass"), "{err}");
    assert!(ModelSpec::parse(json, Some(Template::Pendulum)).is_ok());
    // A template whose dimensions do not fit the data is refused before training.
    let spec = ModelSpec::named("W-B", Some(Template::Pendulum)).unwrap();
    let err = Trainer::new(
        "W-B",
        spec,
        &[],
        &data(&Template::DoublePendulum, 8, 0),
        None,
        quick(1),
        &flex(),
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("nv = 1"), "{err}");
}

/// One training step on flex and on ndarray from the same initialization. f32 rounding differs
/// between the backends' kernels, so 1e-4 relative.
#[test]
fn flex_and_ndarray_agree_on_a_training_step() {
    let train = data(&Template::DoublePendulum, 64, 3);
    let cfg = TrainConfig {
        epochs: 1,
        batch_size: 64,
        val_fraction: 0.0,
        ..TrainConfig::default()
    };
    let mut out = vec![];
    for b in [Backend::Flex, Backend::Ndarray] {
        let dev = device(b, Precision::F32).unwrap().autodiff();
        let spec = ModelSpec::named("MVF", None).unwrap();
        let mut trainer = Trainer::new("MVF", spec, &[], &train, None, cfg.clone(), &dev).unwrap();
        let m = trainer.run_epoch(&AtomicBool::new(false)).unwrap();
        let params: Vec<f64> = trainer
            .model()
            .params
            .export()
            .into_iter()
            .flat_map(|a| a.values)
            .collect();
        out.push((m.train_loss, params));
    }
    let (a, b) = (&out[0], &out[1]);
    assert!(
        (a.0 - b.0).abs() <= 1e-4 * a.0.abs(),
        "loss {} vs {}",
        a.0,
        b.0
    );
    assert!(common::rel_err(&a.1, &b.1) < 1e-4);
    // The step moved the parameters: the comparison is not of two initializations.
    let spec = ModelSpec::named("MVF", None).unwrap();
    let fresh = Trainer::new("MVF", spec, &[], &train, None, cfg, &flex()).unwrap();
    let init: Vec<f64> = fresh
        .model()
        .params
        .export()
        .into_iter()
        .flat_map(|a| a.values)
        .collect();
    assert!(common::rel_err(&a.1, &init) > 1e-5);
}

/// A run checkpointed at epoch k, serialized, and resumed equals the uninterrupted run bit for
/// bit (parameters, best parameters, losses).
#[test]
fn resumed_run_equals_uninterrupted_run() {
    let train = data(&Template::DoublePendulum, 96, 4);
    let cfg = quick(5);
    let never = AtomicBool::new(false);
    for name in ["MVF", "W-B"] {
        let spec = ModelSpec::named(name, Some(Template::DoublePendulum)).unwrap();
        let init = [("m1".to_string(), 12.0)];
        let init: &[(String, f64)] = if name == "W-B" { &init } else { &[] };
        let mut full =
            Trainer::new(name, spec.clone(), init, &train, None, cfg.clone(), &flex()).unwrap();
        full.run(&never, |_, _| {}).unwrap();

        let mut first = Trainer::new(name, spec, init, &train, None, cfg.clone(), &flex()).unwrap();
        for _ in 0..2 {
            first.run_epoch(&never).unwrap();
        }
        let bytes = first.checkpoint().to_bytes();
        drop(first);
        let state = TrainState::from_bytes(&bytes).unwrap();
        let mut resumed = Trainer::resume(state, &train, None, &flex()).unwrap();
        assert_eq!(resumed.epoch(), 2);
        // Everything the checkpoint held was restored: taken again, it is the same bytes.
        assert!(resumed.checkpoint().to_bytes() == bytes, "{name}");
        resumed.run(&never, |_, _| {}).unwrap();

        assert_eq!(
            full.model().params.export(),
            resumed.model().params.export(),
            "{name}"
        );
        let (a, b) = (full.model_file(), resumed.model_file());
        assert_eq!(a.params, b.params);
        let (ra, rb) = (a.report.unwrap(), b.report.unwrap());
        let losses = |r: &graybox::model::report::TrainReport| {
            r.history
                .iter()
                .map(|h| (h.train_loss, h.val_loss))
                .collect::<Vec<_>>()
        };
        assert_eq!(losses(&ra), losses(&rb));
        assert_eq!(ra.best_epoch, rb.best_epoch);
    }
}

/// Threads split each batch into shards: a run on 2 threads is the same bit for bit every
/// time, and a checkpoint of it resumed on 1 thread keeps the 2-shard split and equals the
/// uninterrupted run bit for bit.
#[test]
fn threaded_runs_repeat_and_resume_bit_equal_on_other_thread_counts() {
    let train = data(&Template::DoublePendulum, 512, 5);
    let cfg = TrainConfig {
        epochs: 3,
        batch_size: 256,
        ..TrainConfig::default()
    };
    let never = AtomicBool::new(false);
    let spec = ModelSpec::named("MVF", None).unwrap();
    let start = |threads| {
        Trainer::new("MVF", spec.clone(), &[], &train, None, cfg.clone(), &flex())
            .unwrap()
            .with_threads(threads)
            .unwrap()
    };
    let mut a = start(2);
    a.run(&never, |_, _| {}).unwrap();
    let mut b = start(2);
    b.run(&never, |_, _| {}).unwrap();
    assert_eq!(a.model().params.export(), b.model().params.export());

    let mut first = start(2);
    first.run_epoch(&never).unwrap();
    let state = TrainState::from_bytes(&first.checkpoint().to_bytes()).unwrap();
    assert_eq!(state.shards, 2);
    let mut resumed = Trainer::resume(state, &train, None, &flex())
        .unwrap()
        .with_threads(1)
        .unwrap();
    assert_eq!(resumed.shards(), 2, "a resumed run keeps its split");
    resumed.run(&never, |_, _| {}).unwrap();
    assert_eq!(a.model().params.export(), resumed.model().params.export());
    assert_eq!(a.model_file().params, resumed.model_file().params);

    // The split is what changes the numbers: one shard is another (equally valid) run.
    let mut single = start(1);
    single.run(&never, |_, _| {}).unwrap();
    assert_eq!(single.shards(), 1);
    assert_ne!(a.model().params.export(), single.model().params.export());
    assert!(start(1).with_threads(0).is_err(), "0 threads is refused");
    assert!(start(1).with_threads(100_000).is_err(), "a typo is refused");
}

/// The job budget's parameter count (what `--max-model-params` refuses on) is the count the
/// trained model has, angles (one more network input each) and templates included.
#[test]
fn the_budget_counts_the_parameters_a_model_has() {
    use burn::module::Module;
    use graybox::train::budget::{Dims, estimate};
    let train = data(&Template::DoublePendulum, 64, 1);
    for name in ["MVF", "naive", "MVB", "MB", "VB", "F", "W-B"] {
        for periodic in [vec![], vec![true, true], vec![true, false]] {
            let spec = ModelSpec::named(name, Some(Template::DoublePendulum)).unwrap();
            let cfg = TrainConfig {
                periodic: periodic.clone(),
                ..quick(1)
            };
            let t = Trainer::new(name, spec.clone(), &[], &train, None, cfg, &flex()).unwrap();
            let dims = Dims {
                n: 2,
                m: 2,
                angles: periodic.iter().filter(|&&a| a).count(),
            };
            let physical = t.model().physical_values().map_or(0, |v| v.len());
            let est = estimate(&spec, dims, 32, 64, physical);
            assert_eq!(
                est.params,
                t.model().params.num_params(),
                "{name}, periodic {periodic:?}"
            );
        }
    }
}

/// Model-based RL grows its data between episodes: `extend` trains on from the same
/// parameters (the first data's loss is not reset by it), a checkpoint taken after it resumes
/// on the grown data bit-equal to an uninterrupted run, and data of another shape is refused.
#[test]
fn extended_run_trains_on_and_resumes_on_the_grown_data() {
    let first = data(&Template::DoublePendulum, 32, 11);
    let more = data(&Template::DoublePendulum, 64, 12);
    let grown = {
        let idx: Vec<usize> = (0..64).collect();
        let m = more.subset(&idx);
        let cat = |a: &[f64], b: &[f64]| [a, b].concat();
        Dataset::new(
            first.dt,
            (2, 2),
            2,
            [
                cat(&first.q, &m.q),
                cat(&first.qdot, &m.qdot),
                cat(&first.u, &m.u),
                cat(&first.q_next, &m.q_next),
                cat(&first.qdot_next, &m.qdot_next),
            ],
        )
        .unwrap()
    };
    let cfg = TrainConfig {
        val_fraction: 0.0,
        ..quick(3)
    };
    let never = AtomicBool::new(false);
    let spec = ModelSpec::named("MVB", Some(Template::DoublePendulum)).unwrap();
    let start = |cfg: &TrainConfig| {
        let mut t =
            Trainer::new("MVB", spec.clone(), &[], &first, None, cfg.clone(), &flex()).unwrap();
        t.run(&never, |_, _| {}).unwrap();
        t
    };
    let mut full = start(&cfg);
    let before = full.model().params.export();
    full.extend(&grown, 4, grown.count()).unwrap();
    assert_eq!(
        full.model().params.export(),
        before,
        "extend keeps the parameters"
    );
    full.run(&never, |_, _| {}).unwrap();
    assert_eq!(full.epoch(), 7);
    assert_ne!(full.model().params.export(), before, "and trains them on");

    let mut cut = start(&cfg);
    cut.extend(&grown, 4, grown.count()).unwrap();
    cut.run_epoch(&never).unwrap();
    let state = TrainState::from_bytes(&cut.checkpoint().to_bytes()).unwrap();
    assert!(Trainer::resume(state.clone(), &first, None, &flex()).is_err());
    let mut resumed = Trainer::resume(state, &grown, None, &flex()).unwrap();
    resumed.run(&never, |_, _| {}).unwrap();
    assert_eq!(
        full.model().params.export(),
        resumed.model().params.export()
    );

    let other = data(&Template::Pendulum, 8, 1);
    let e = full.extend(&other, 1, 8).unwrap_err();
    assert!(e.to_string().contains("data"), "{e}");
}

#[test]
fn cancel_flag_stops_training() {
    let train = data(&Template::DoublePendulum, 64, 5);
    let spec = ModelSpec::named("MVF", None).unwrap();
    let mut t = Trainer::new("MVF", spec, &[], &train, None, quick(3), &flex()).unwrap();
    let err = t.run_epoch(&AtomicBool::new(true)).unwrap_err();
    assert!(matches!(err, Error::Cancelled));
    assert_eq!(t.epoch(), 0);
}

#[test]
fn non_finite_loss_is_an_error_naming_the_epoch() {
    let mut bad = data(&Template::DoublePendulum, 16, 6);
    for v in &mut bad.q_next {
        *v = 1e30; // squared error overflows f32
    }
    let spec = ModelSpec::named("MVF", None).unwrap();
    let mut t = Trainer::new("MVF", spec, &[], &bad, None, quick(2), &flex()).unwrap();
    let err = t.run(&AtomicBool::new(false), |_, _| {}).unwrap_err();
    assert!(
        matches!(&err, Error::Training(msg) if msg.contains("epoch 1")),
        "{err}"
    );
}

/// The saved model is the best-validation one: evaluating the file on the validation set
/// gives the reported best validation loss.
#[test]
fn saved_model_is_the_best_validation_model() {
    let train = data(&Template::DoublePendulum, 128, 7);
    let val = data(&Template::DoublePendulum, 64, 8);
    let spec = ModelSpec::named("MVB", None).unwrap();
    let cfg = TrainConfig {
        epochs: 6,
        batch_size: 32,
        lr: 3e-2,
        ..TrainConfig::default()
    };
    let mut t = Trainer::new("MVB", spec, &[], &train, Some(&val), cfg, &flex()).unwrap();
    t.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let file = t.model_file();
    let report = file.report.clone().unwrap();
    let model = Model::from_file(&file, &device(Backend::Flex, Precision::F32).unwrap()).unwrap();
    let loss = evaluate(&model, &val).unwrap();
    let best = report.best_val_loss.unwrap();
    assert!(
        (loss - best).abs() <= 1e-6 * best,
        "eval {loss} vs best {best}"
    );
    let min = report
        .history
        .iter()
        .filter_map(|h| h.val_loss)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(best, min);
}

#[test]
fn early_stopping_keeps_the_best_epoch() {
    let train = data(&Template::DoublePendulum, 64, 9);
    let val = data(&Template::DoublePendulum, 32, 10);
    let spec = ModelSpec::named("naive", None).unwrap();
    // 64 samples and a large learning rate: the naive net overfits and oscillates, so the
    // validation loss stops improving long before 500 epochs.
    let cfg = TrainConfig {
        epochs: 500,
        batch_size: 16,
        lr: 0.05,
        patience: Some(3),
        ..TrainConfig::default()
    };
    let mut t = Trainer::new("naive", spec, &[], &train, Some(&val), cfg, &flex()).unwrap();
    t.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let r = t.report();
    assert!(r.stopped_early && r.epochs < 500, "ran {} epochs", r.epochs);
    assert_eq!(r.epochs, r.best_epoch + 3);
    let best = r.history[r.best_epoch - 1].val_loss.unwrap();
    assert_eq!(r.best_val_loss, Some(best));
    assert!(
        r.history[r.best_epoch..]
            .iter()
            .all(|h| h.val_loss.unwrap() >= best)
    );
}

/// The silent bad run of issue 11: the paper's data with its angles in degrees, trained W-B.
/// It "succeeds", but its report (and so the job) carries warnings that say why not to trust it.
#[test]
fn a_run_on_degrees_warns() {
    let mut ds = data(&Template::DoublePendulum, 256, 5);
    for a in [&mut ds.q, &mut ds.qdot, &mut ds.q_next, &mut ds.qdot_next] {
        a.iter_mut().for_each(|v| *v = v.to_degrees());
    }
    assert!(!ds.warnings().is_empty(), "the data's own checks fire too");
    let spec = ModelSpec::named("W-B", Some(Template::DoublePendulum)).unwrap();
    let mut t = Trainer::new("W-B", spec, &[], &ds, None, quick(6), &flex()).unwrap();
    t.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let codes: Vec<String> = t.report().warnings.into_iter().map(|w| w.code).collect();
    assert!(
        codes.contains(&"no_better_than_zero_acceleration".to_string()),
        "{codes:?}"
    );
}

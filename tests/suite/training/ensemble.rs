//! Ensembles: one member is a single model's run byte for byte; members differ by their
//! seeds and resamples; an ensemble resumes bit for bit, whichever unit its threads run by;
//! cancel stops every member; the model file holds every member.

use std::sync::atomic::AtomicBool;

use graybox::error::Error;
use graybox::model::Model;
use graybox::model::file::{FORMAT_ENSEMBLE, ModelFile};
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::train::{Ensemble, Parallelism, TrainConfig, TrainState, Trainer};

use super::{data, flex, quick};

fn ensemble(k: usize, bootstrap: bool, epochs: usize) -> TrainConfig {
    TrainConfig {
        ensemble: k,
        bootstrap,
        ..quick(epochs)
    }
}

fn mvf() -> ModelSpec {
    ModelSpec::named("MVF", None).unwrap()
}

/// A new MVF ensemble on `train` (no validation set).
fn mvf_ensemble(train: &graybox::data::Dataset, cfg: TrainConfig) -> Ensemble {
    Ensemble::new("MVF", mvf(), &[], train, None, cfg, &flex()).unwrap()
}

fn run(e: &mut Ensemble) {
    let never = AtomicBool::new(false);
    while !e.finished() {
        e.run_epoch(&never).unwrap();
    }
}

#[test]
fn one_member_is_a_single_models_run_byte_for_byte() {
    let train = data(&Template::DoublePendulum, 96, 11);
    let never = AtomicBool::new(false);
    let mut single = Trainer::new("MVF", mvf(), &[], &train, None, quick(3), &flex()).unwrap();
    let mut one = mvf_ensemble(&train, quick(3));
    single.run_epoch(&never).unwrap();
    one.run_epoch(&never).unwrap();
    assert!(
        without_times(&one.checkpoint()) == without_times(&single.checkpoint().to_bytes()),
        "the same checkpoint"
    );
    single.run(&never, |_, _| {}).unwrap();
    run(&mut one);
    let (a, b) = (single.model_file(), one.model_file());
    assert_eq!(
        a.format, b.format,
        "one member writes a single model's format"
    );
    assert!(without_times(&a.to_bytes().unwrap()) == without_times(&b.to_bytes().unwrap()));
}

/// JSON bytes with every measured time ("seconds", "train_seconds", "member_seconds",
/// "samples_per_second") set to 0: two runs differ in nothing else.
fn without_times(bytes: &[u8]) -> String {
    fn walk(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(o) => {
                for (k, x) in o.iter_mut() {
                    if [
                        "seconds",
                        "train_seconds",
                        "member_seconds",
                        "samples_per_second",
                    ]
                    .contains(&k.as_str())
                    {
                        *x = serde_json::json!(0);
                    } else {
                        walk(x);
                    }
                }
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(walk),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
    walk(&mut v);
    v.to_string()
}

#[test]
fn members_differ_by_seed_and_by_resample() {
    let train = data(&Template::DoublePendulum, 96, 12);
    let single = {
        let mut t = Trainer::new("MVF", mvf(), &[], &train, None, quick(2), &flex()).unwrap();
        t.run(&AtomicBool::new(false), |_, _| {}).unwrap();
        t.model().params.export()
    };
    let params = |bootstrap| {
        let cfg = ensemble(3, bootstrap, 2);
        let mut e = mvf_ensemble(&train, cfg);
        run(&mut e);
        let members = e.members().iter().map(|m| m.model().params.export());
        members.collect::<Vec<_>>()
    };
    // Without resamples member 0 has the job's seed: it is the single model.
    let same_data = params(false);
    assert_eq!(same_data[0], single);
    assert_ne!(same_data[1], same_data[0], "member 1 has its own seed");
    assert_ne!(same_data[2], same_data[1], "member 2 has its own seed");
    // With them, member 0 starts as the single model but sees other rows.
    let resampled = params(true);
    assert_ne!(resampled[0], single, "member 0 trains on a resample");
    assert_ne!(resampled[1], same_data[1]);
}

/// A checkpoint after 2 of 4 epochs, resumed (on members side by side where the first part
/// ran members one after another with two shards each), ends with the uninterrupted run's
/// file, byte for byte.
#[test]
fn an_ensemble_resumes_bit_for_bit_whichever_unit_its_threads_run() {
    let train = data(&Template::DoublePendulum, 512, 13);
    let val = data(&Template::DoublePendulum, 64, 14);
    let cfg = TrainConfig {
        batch_size: 256,
        ..ensemble(3, true, 4)
    };
    let start = || {
        Ensemble::new("MVF", mvf(), &[], &train, Some(&val), cfg.clone(), &flex())
            .unwrap()
            .with_parallelism(2, Parallelism::Rows)
            .unwrap()
    };
    let mut full = start();
    run(&mut full);
    let mut first = start();
    let never = AtomicBool::new(false);
    for _ in 0..2 {
        let epoch = first.run_epoch(&never).unwrap();
        let std = epoch.std.expect("an ensemble's epoch has a spread");
        assert!(std.train_loss > 0.0 && std.val_loss.unwrap() > 0.0);
    }
    let bytes = first.checkpoint();
    drop(first);
    let mut resumed = Ensemble::resume(&bytes, &train, Some(&val), &flex())
        .unwrap()
        .with_parallelism(2, Parallelism::Members)
        .unwrap();
    assert_eq!(resumed.epoch(), 2);
    assert!(
        resumed.checkpoint() == bytes,
        "the checkpoint was restored in full"
    );
    run(&mut resumed);
    let (a, b) = (full.model_file(), resumed.model_file());
    assert!(without_times(&a.to_bytes().unwrap()) == without_times(&b.to_bytes().unwrap()));
    let member = |bytes: &[u8], k: usize| {
        let text = std::str::from_utf8(bytes).unwrap();
        let v: serde_json::Value = serde_json::from_str(text).unwrap();
        TrainState::from_bytes(v["members"][k].to_string().as_bytes()).unwrap()
    };
    assert_eq!(member(&bytes, 2).member, 2);
    assert_eq!(
        member(&bytes, 0).shards,
        2,
        "the first part split its batches"
    );
    assert!(
        Ensemble::resume(
            &bytes,
            &data(&Template::DoublePendulum, 512, 99),
            Some(&val),
            &flex()
        )
        .is_err(),
        "a resume on other data is refused"
    );
}

#[test]
fn cancel_stops_every_member_and_bad_sizes_are_refused() {
    let train = data(&Template::DoublePendulum, 64, 15);
    let mut e = mvf_ensemble(&train, ensemble(3, true, 2))
        .with_threads(2)
        .unwrap();
    let err = e.run_epoch(&AtomicBool::new(true)).unwrap_err();
    assert!(matches!(err, Error::Cancelled), "{err}");
    assert!(e.members().iter().all(|m| m.epoch() == 0));
    for k in [0, 33] {
        let err = Ensemble::new(
            "MVF",
            mvf(),
            &[],
            &train,
            None,
            ensemble(k, true, 2),
            &flex(),
        )
        .err()
        .unwrap();
        assert!(err.to_string().contains("training.ensemble"), "{err}");
    }
}

/// The file holds every member and reads back as the same members; a white-box ensemble's
/// report gives each physical parameter's mean and spread across its members.
#[test]
fn the_model_file_holds_every_member_and_the_physical_spread() {
    let train = data(&Template::DoublePendulum, 128, 16);
    let spec = ModelSpec::named("W-B", Some(Template::DoublePendulum)).unwrap();
    let init = [("m1".to_string(), 12.0)];
    let cfg = ensemble(3, true, 3);
    let mut e = Ensemble::new("W-B", spec, &init, &train, None, cfg, &flex()).unwrap();
    run(&mut e);
    let file = ModelFile::from_bytes(&e.model_file().to_bytes().unwrap()).unwrap();
    assert_eq!(file.format, FORMAT_ENSEMBLE);
    assert_eq!(file.member_count(), 3);
    for (k, m) in e.members().iter().enumerate() {
        assert_eq!(file.member(k).params, m.model_file().params, "member {k}");
    }
    let report = file.report.unwrap();
    let spread = report.ensemble.as_ref().unwrap();
    assert_eq!(spread.members.len(), 3);
    let m1: Vec<f64> = (spread.members.iter())
        .map(|m| m.physical_parameters["m1"])
        .collect();
    let s = spread.physical_parameters["m1"];
    let mean = m1.iter().sum::<f64>() / 3.0;
    let var = m1.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 2.0;
    // The same sums in another order: equal to rounding.
    assert!((s.mean - mean).abs() <= 1e-12 * mean.abs() && s.std > 0.0);
    assert!((s.std - var.sqrt()).abs() <= 1e-9 * s.std);
    assert_eq!(report.physical_parameters["m1"], s.mean);
}

/// The evaluator of an ensemble's file answers with its members' mean: x' against each
/// member's own evaluator (loaded from its own file), σ against the members' spread computed
/// here, A and B against the members' own linearizations; rollouts follow the mean step.
#[test]
fn an_ensembles_evaluator_answers_with_its_members_mean() {
    use graybox::infer::Evaluator;
    let train = data(&Template::DoublePendulum, 128, 17);
    let mut e = mvf_ensemble(&train, ensemble(3, true, 2));
    run(&mut e);
    let file = ModelFile::from_bytes(&e.model_file().to_bytes().unwrap()).unwrap();
    let eval = Evaluator::from_file(&file).unwrap();
    assert_eq!(eval.member_count(), 3);
    let own: Vec<Evaluator> = (0..3)
        .map(|k| Evaluator::from_file(&file.member(k)).unwrap())
        .collect();
    let x = [0.3, -0.2, 1.0, 0.5, -1.2, 0.7, 0.1, -2.0];
    let u = [0.5, -0.5, 1.0, 2.0];
    let each: Vec<Vec<f64>> = own.iter().map(|m| m.predict(&x, &u, false).0).collect();
    let (mean, _) = eval.predict(&x, &u, false);
    let p = eval
        .predict_members_until(&x, &u, eval.config.dt, false, &|| false)
        .unwrap();
    // Sums of three numbers in another order: equal to a few ulps of the largest.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs()));
    for i in 0..x.len() {
        let v: Vec<f64> = each.iter().map(|m| m[i]).collect();
        let want = v.iter().sum::<f64>() / 3.0;
        let sd = (v.iter().map(|a| (a - want).powi(2)).sum::<f64>() / 2.0).sqrt();
        assert!(close(mean[i], want), "{i}: {} vs {want}", mean[i]);
        assert!(close(p.std[i], sd) && sd > 0.0, "{i}: {} vs {sd}", p.std[i]);
        assert_eq!(p.mean[i], mean[i], "Predict's mean is the evaluator's");
        assert_eq!(p.next.iter().map(|m| m[i]).collect::<Vec<_>>(), v);
    }
    let (a, b) = eval.linearize_batch(&x, &u);
    let lin: Vec<(Vec<f64>, Vec<f64>)> = own.iter().map(|m| m.linearize_batch(&x, &u)).collect();
    for (i, v) in a.iter().enumerate() {
        assert!(
            close(*v, lin.iter().map(|l| l.0[i]).sum::<f64>() / 3.0),
            "A {i}"
        );
    }
    for (i, v) in b.iter().enumerate() {
        assert!(
            close(*v, lin.iter().map(|l| l.1[i]).sum::<f64>() / 3.0),
            "B {i}"
        );
    }
    let mut states = vec![];
    eval.rollout(
        &x[..4],
        (2, eval.config.dt),
        |_, _| u[..2].to_vec(),
        |x, _| {
            states.push(x.to_vec());
            true
        },
    );
    assert_eq!(states[0], eval.predict(&x[..4], &u[..2], false).0);
    // One member's evaluator is a single model's.
    assert_eq!(own[1].member_count(), 1);
    assert_eq!(
        own[1]
            .predict_members_until(&x, &u, own[1].config.dt, false, &|| false)
            .unwrap()
            .std,
        vec![0.0; 8]
    );
}

/// `eval` of an ensemble (`evaluate_members`): each member's loss is its own `evaluate`; the
/// ensemble's is the loss of the members' mean prediction, here taken from the f64 evaluator
/// rather than averaged in Burn; the prediction spread is the evaluator's σ, RMS over rows.
#[test]
fn an_ensembles_eval_is_its_mean_predictions_loss() {
    use burn::tensor::{Tensor, TensorData};
    use graybox::backend::{Backend, Precision, device};
    use graybox::infer::Evaluator;
    use graybox::train::trainer::{evaluate, evaluate_members};
    let train = data(&Template::DoublePendulum, 128, 17);
    let mut e = mvf_ensemble(&train, ensemble(3, true, 2));
    run(&mut e);
    let file = e.model_file();
    // This process computes in f32 (fixed per process); the evaluator in f64.
    let dev = device(Backend::Flex, Precision::F32).unwrap();
    let models: Vec<_> = (0..3)
        .map(|k| Model::from_file(&file.member(k), &dev).unwrap())
        .collect();
    let test = data(&Template::DoublePendulum, 300, 23);
    let got = evaluate_members(&models, &test).unwrap();
    for (k, m) in models.iter().enumerate() {
        assert_eq!(got.member_losses[k], evaluate(m, &test).unwrap());
    }
    let (x, y) = test.states();
    let eval = Evaluator::from_file(&file).unwrap();
    let p = eval
        .predict_members_until(&x, &test.u, eval.config.dt, false, &|| false)
        .unwrap();
    let rows = test.count();
    let tensor = |v: Vec<f64>| Tensor::<2>::from_data(TensorData::new(v, [rows, 4]), &dev);
    let sum = models[0].error_sum(tensor(p.mean.clone()), tensor(y));
    let want = sum.into_data().iter::<f64>().next().unwrap() / rows as f64;
    // Relative 1e-4: f32 steps (relative error ~1e-7 on states of order 10) against f64 ones,
    // on errors of order 0.1 after two epochs, squared; a wrong mean (member 0's, or an
    // unweighted one) is off by percents.
    assert!(
        (got.loss - want).abs() <= 1e-4 * want,
        "{} vs {want}",
        got.loss
    );
    // The mean's squared error is at most the members' mean one (Jensen), and not member 0's.
    let members_mean = got.member_losses.iter().sum::<f64>() / 3.0;
    assert!(got.loss <= members_mean && got.loss != got.member_losses[0]);
    for (i, s) in got.prediction_std.iter().enumerate() {
        let ms = p.std.iter().skip(i).step_by(4).map(|v| v * v).sum::<f64>() / rows as f64;
        // Relative 1e-4: the f32 steps' rounding in the members' differences (measured: 2e-6
        // at worst, on σ of 4e-4).
        assert!(
            (s - ms.sqrt()).abs() <= 1e-4 * ms.sqrt() && *s > 0.0,
            "σ {i}"
        );
    }
}

/// An ensemble validated on trajectories reports its open-loop error against horizon once, on
/// its mean dynamics (what the service rolls out), not member 0's.
#[test]
fn an_ensembles_horizon_errors_are_its_mean_dynamics() {
    use graybox::infer::Evaluator;
    use graybox::infer::horizons::horizon_errors;
    use graybox::sim::double_pendulum_trajectories;
    let train = double_pendulum_trajectories(3, 20, 5).unwrap();
    let val = double_pendulum_trajectories(2, 12, 6).unwrap();
    let cfg = ensemble(3, true, 2);
    let mut e = Ensemble::new("MVF", mvf(), &[], &train, Some(&val), cfg, &flex()).unwrap();
    run(&mut e);
    let file = e.model_file();
    let found = &file.report.as_ref().unwrap().horizon_errors;
    let horizons: Vec<usize> = found.iter().map(|h| h.horizon).collect();
    assert_eq!(horizons, [1, 10], "the horizons 12-step trajectories reach");
    let on = |f: &ModelFile| {
        let eval = Evaluator::from_file(f).unwrap();
        horizon_errors(&eval, &val, &horizons, &|| false).unwrap()
    };
    assert_eq!(found, &on(&file));
    assert_ne!(
        found,
        &on(&file.member(0)),
        "member 0 alone rolls out otherwise"
    );
}

/// Model-based RL grows an ensemble's data after every episode. `extend` keeps each member on
/// its own resample, drawn from the grown data as a resumed member draws it, so a checkpoint
/// taken after `extend` resumes to the members the uninterrupted run trains.
#[test]
fn an_extended_ensemble_resumes_to_the_same_members() {
    let first = data(&Template::DoublePendulum, 48, 3);
    let grown = data(&Template::DoublePendulum, 96, 4);
    let cfg = TrainConfig {
        val_fraction: 0.0,
        ..ensemble(3, true, 2)
    };
    let started = || {
        let mut e = mvf_ensemble(&first, cfg.clone());
        run(&mut e);
        e.extend(&grown, 3, grown.count()).unwrap();
        e
    };
    let mut whole = started();
    run(&mut whole);
    assert_eq!(whole.epoch(), 5);

    let mut cut = started();
    cut.run_epoch(&AtomicBool::new(false)).unwrap();
    let mut resumed = Ensemble::resume_states(cut.states(), &grown, None, &flex()).unwrap();
    run(&mut resumed);
    let params = |e: &Ensemble| -> Vec<_> {
        (e.members().iter())
            .map(|m| m.model().params.export())
            .collect()
    };
    assert_eq!(params(&whole), params(&resumed));
    let p = params(&whole);
    assert!(p[0] != p[1] && p[1] != p[2], "the members differ");
}

//! The efforts' delay (docs/robots.md#effort-delay): a log whose efforts act two steps after
//! they were logged (a drive's command path) gives its delay back to the least squares and
//! to training on the torque loss, which reads each step's effort as the mean of the log's
//! held samples shifted by the delay; a state loss, which has no such rows, is refused.

use super::*;
use graybox::physics::integrator::Integrator;
use graybox::physics::urdf::delay;
use graybox::rng::Rng;
use graybox::sim::{TemplateSystem, true_step};
use graybox::train::objective::Objective;

const DT: f64 = 0.01;
/// Two steps: the truth.
const DELAY: f64 = 0.02;
/// The document's bound.
const BOUND: f64 = 0.05;

fn delayed_pendulum() -> Template {
    let text = std::fs::read_to_string(common::urdf::fixture_path("double_pendulum", "urdf"));
    let doc = serde_json::json!({"kind": "urdf", "urdf": text.unwrap(), "effort_delay": BOUND});
    Template::from_document(&doc).unwrap()
}

/// The template's defaults with the delay at `DELAY` (its last value).
fn truth(t: &Template) -> Vec<f64> {
    let mut p = t.defaults();
    *p.last_mut().unwrap() = DELAY;
    p
}

/// `count` trajectories of `steps` transitions of the robot at `truth`, recorded every DT of
/// RK4 at DT/10, whose logged effort u_k acts over step k + 2: the applied a_{k+2}. Efforts
/// are drawn afresh every step (σ 60 N·m) after three equal ones, which the log's first
/// sample stands for (what a log says of the time before it).
fn delayed_log(t: &Template, count: usize, steps: usize, seed: u64) -> Dataset {
    let (n, m) = (t.space().nv(), t.m());
    let sys = TemplateSystem::new(t.clone(), truth(t));
    let mut rng = Rng::derive(seed, 7);
    let mut arrays: [Vec<f64>; 5] = Default::default();
    for _ in 0..count {
        let mut x: Vec<f64> = (0..n).map(|_| rng.uniform_in(-3.0, 3.0)).collect();
        x.extend((0..n).map(|_| rng.uniform_in(-2.0, 2.0)));
        let first: Vec<f64> = (0..m).map(|_| 60.0 * rng.normal()).collect();
        let applied: Vec<Vec<f64>> = (0..steps)
            .map(|k| match k {
                0..3 => first.clone(),
                _ => (0..m).map(|_| 60.0 * rng.normal()).collect(),
            })
            .collect();
        for k in 0..steps {
            let mut next = x.clone();
            for _ in 0..10 {
                next = true_step(&sys, &next, &applied[k], DT / 10.0, Integrator::Rk4);
            }
            arrays[0].extend(&x[..n]);
            arrays[1].extend(&x[n..]);
            arrays[2].extend(&applied[(k + 2).min(steps - 1)]);
            arrays[3].extend(&next[..n]);
            arrays[4].extend(&next[n..]);
            x = next;
        }
    }
    let ds = Dataset::new(DT, (n, n), m, arrays).unwrap();
    ds.with_trajectories(vec![steps; count]).unwrap()
}

/// The least squares' search over the delay finds two steps within 2 % of a step (measured
/// 0.66 %: the midpoint reading's O(Δt²) under efforts that jump every step is all that is
/// off; a search that did not move, or a weight on the wrong sample, is a step or more
/// away) and the base parameters within 1e-3 as on a log without a delay (the same
/// reading's error), where reading the log without its delay leaves them 85 % off.
#[test]
fn least_squares_finds_the_effort_delay() {
    let t = delayed_pendulum();
    let Template::Urdf(u) = &t else {
        unreachable!()
    };
    let ds = delayed_log(&t, 8, 128, 1);
    let lags = delay::lags(BOUND, DT);
    let rows = graybox::train::objective::torque_rows(&ds, &t.space(), lags);
    let mut start: Vec<f64> = truth(&t).iter().map(|v| 1.3 * v).collect();
    *start.last_mut().unwrap() = 0.0;
    let ls = u
        .least_squares(&start, true, (&rows, lags), &|| false)
        .unwrap();
    let got = *ls.physical.last().unwrap();
    eprintln!("delay {got:e}");
    assert!((got - DELAY).abs() < 0.02 * DT, "delay {got}");
    let e = super::torque::base_error(u, &ls.physical, &truth(&t));
    assert!(e <= 1e-3, "‖Δβ‖/‖β‖ = {e:.2e}");
    // Read without the delay, the same log leaves a residual the search has to beat.
    let rows0 = graybox::train::objective::torque_rows(&ds, &t.space(), 0);
    let plain = urdf_pendulum_doc();
    let Template::Urdf(p) = &plain else {
        unreachable!()
    };
    let n = start.len() - 1;
    let ls0 = p
        .least_squares(&start[..n], true, (&rows0, 0), &|| false)
        .unwrap();
    let e0 = super::torque::base_error(p, &ls0.physical, &t.defaults()[..n]);
    assert!(
        e0 > 10.0 * e.max(1e-4),
        "without the delay ‖Δβ‖/‖β‖ = {e0:.2e}"
    );
}

fn urdf_pendulum_doc() -> Template {
    let text = std::fs::read_to_string(common::urdf::fixture_path("double_pendulum", "urdf"));
    Template::from_document(&serde_json::json!({"kind": "urdf", "urdf": text.unwrap()})).unwrap()
}

/// Training on the torque loss moves the delay from 0.8 steps off to the truth within a
/// twentieth of a step (the gradient reaches δ through the shifted mean's slope; without it
/// δ stays where it started), every other value starting at the truth.
#[test]
fn the_torque_loss_learns_the_effort_delay() {
    let t = delayed_pendulum();
    let train = delayed_log(&t, 8, 128, 2);
    let init: Vec<(String, f64)> = (t.params().iter().zip(truth(&t)))
        .map(|(p, v)| (p.name.to_string(), v))
        .map(|(name, v)| match name.as_str() {
            "effort_delay" => (name, DELAY - 0.8 * DT),
            _ => (name, v),
        })
        .collect();
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let cfg = TrainConfig {
        epochs: 20,
        batch_size: 64,
        lr: 5e-4,
        loss: Objective::TORQUE,
        ..TrainConfig::default()
    };
    let mut run = Trainer::new("W-B", spec.clone(), &init, &train, None, cfg, &flex()).unwrap();
    run.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let learned = run.model().physical_values().unwrap();
    let got = learned.last().unwrap().1;
    eprintln!("delay {got:e}");
    assert!((got - DELAY).abs() < 0.05 * DT, "delay {got}");
    // The state loss has no rows of earlier efforts.
    let cfg = TrainConfig {
        loss: Objective::STEP,
        ..quick(1)
    };
    let e = Trainer::new("x", spec, &[], &train, None, cfg, &flex())
        .err()
        .unwrap();
    assert!(
        matches!(&e, Error::Invalid { field, .. } if field == "training.loss"),
        "{e}"
    );
}

/// A row's block: the step, the earlier samples' ages, the samples newest first; a
/// trajectory's first sample stands for those before it, the next trajectory's rows do not
/// reach back into this one's.
#[test]
fn torque_rows_carry_the_efforts_before_each_step() {
    let t = delayed_pendulum();
    let ds = delayed_log(&t, 2, 3, 3);
    let rows = graybox::train::objective::torque_rows(&ds, &t.space(), 2);
    let width = 3 * 2 + delay::input_width(2, 2);
    assert_eq!(rows.len(), 6 * width);
    let block = |i: usize| &rows[i * width + 6..(i + 1) * width];
    let u = |i: usize| &ds.u[2 * i..2 * i + 2];
    assert_eq!(&block(2)[..3], [DT, DT, 2.0 * DT]);
    assert_eq!(&block(2)[3..], [u(2), u(1), u(0)].concat());
    assert_eq!(&block(4)[3..], [u(4), u(3), u(3)].concat());
}

/// The torque loss's gradient in δ against the change of the loss itself: within a piece
/// the weights are linear in δ and the loss quadratic, so the mean of the gradients at both
/// ends times the step is the change exactly; 1e-3 of it allows the f32 loss's rounding
/// (~3e-7 of 2.5 over a change of 0.06). A gradient that did not reach δ is 0.
#[test]
fn the_delay_s_gradient_is_the_loss_s_slope() {
    let t = delayed_pendulum();
    let train = delayed_log(&t, 8, 128, 2);
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let (a, b) = (0.012, 0.0121);
    let at = |d: f64| {
        let init: Vec<(String, f64)> = (t.params().iter().zip(truth(&t)))
            .map(|(p, v)| {
                (
                    p.name.to_string(),
                    if p.name == "effort_delay" { d } else { v },
                )
            })
            .collect();
        let cfg = TrainConfig {
            loss: Objective::TORQUE,
            ..quick(1)
        };
        let run = Trainer::new("W-B", spec.clone(), &init, &train, None, cfg, &flex()).unwrap();
        let (loss, g) = run.loss_and_grads(&(0..64).collect::<Vec<usize>>());
        let g = g[0]
            .clone()
            .unwrap()
            .into_data()
            .iter::<f64>()
            .last()
            .unwrap();
        (loss, g)
    };
    let ((la, ga), (lb, gb)) = (at(a), at(b));
    let change = lb - la;
    let predicted = 0.5 * (ga + gb) * (b - a);
    assert!(ga != 0.0, "no gradient reaches δ");
    assert!(
        (predicted - change).abs() < 1e-3 * change.abs(),
        "{predicted} vs {change}"
    );
}

/// A bound that spans more earlier samples than a row may carry is refused before any row
/// is built, naming the document's field (a second at 100 Hz: 126 lags, over 64).
#[test]
fn a_delay_bound_beyond_the_rows_history_is_refused() {
    let text = std::fs::read_to_string(common::urdf::fixture_path("double_pendulum", "urdf"));
    let doc = serde_json::json!({"kind": "urdf", "urdf": text.unwrap(), "effort_delay": 1.0});
    let t = Template::from_document(&doc).unwrap();
    let train = delayed_log(&t, 1, 16, 4);
    let spec = ModelSpec::named("W-B", Some(t)).unwrap();
    let cfg = TrainConfig {
        loss: Objective::TORQUE,
        ..quick(1)
    };
    let e = Trainer::new("x", spec, &[], &train, None, cfg, &flex())
        .err()
        .unwrap();
    assert!(
        matches!(&e, Error::Invalid { field, .. } if field == "template.effort_delay"),
        "{e}"
    );
}

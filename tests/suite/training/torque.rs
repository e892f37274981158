//! The torque loss (docs/training.md#torque-loss): a white-box model trained on the torques
//! its manipulator equation asks for alone identifies the physical values the data were
//! simulated with, a state loss mixed in still trains, and what cannot form a torque is
//! refused naming `training.loss`.

use super::*;
use std::sync::Arc;

use graybox::physics::urdf::UrdfTemplate;
use graybox::train::objective::Objective;

fn urdf_pendulum() -> Template {
    pendulum_from(|text| text)
}

fn pendulum_from(edit: impl Fn(String) -> String) -> Template {
    let text = std::fs::read_to_string(common::urdf::fixture_path("double_pendulum", "urdf"));
    Template::Urdf(Arc::new(
        UrdfTemplate::from_urdf(&edit(text.unwrap())).unwrap(),
    ))
}

/// With rotors of 0.4 and 0.2 kg·m² (a quarter and an eighth of a rod's inertia about its
/// joint).
fn pendulum_with_rotors() -> Template {
    pendulum_from(|text| {
        let first = text.replacen(r#"damping="0.5"/>"#, r#"damping="0.5" armature="0.4"/>"#, 1);
        first.replacen(r#"damping="0.5"/>"#, r#"damping="0.5" armature="0.2"/>"#, 1)
    })
}

/// A W-B model of `t` trained on `objective` from every physical value 30 % off the truth
/// the data were simulated with (far enough that a loss blind to one would leave it there):
/// its learned values and the truth.
fn identify(t: &Template, objective: Objective, epochs: usize) -> (Vec<f64>, Vec<f64>) {
    identify_with(t, objective, epochs, (2e-2, false))
}

/// `identify` at learning rate `lr`, starting from the least-squares solution when
/// `least_squares`.
fn identify_with(
    t: &Template,
    objective: Objective,
    epochs: usize,
    (lr, least_squares): (f64, bool),
) -> (Vec<f64>, Vec<f64>) {
    let train = data(t, 512, 3);
    let truth = t.defaults();
    let init: Vec<(String, f64)> = (t.params().iter().zip(&truth))
        .map(|(p, v)| (p.name.to_string(), 1.3 * v))
        .collect();
    let spec = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    let cfg = TrainConfig {
        epochs,
        batch_size: 64,
        lr,
        loss: objective,
        least_squares,
        ..TrainConfig::default()
    };
    let mut run = Trainer::new("W-B", spec, &init, &train, None, cfg, &flex()).unwrap();
    run.run(&AtomicBool::new(false), |_, _| {}).unwrap();
    let learned = run.model().physical_values().unwrap();
    (learned.into_iter().map(|(_, v)| v).collect(), truth)
}

/// A URDF double pendulum's base parameters (the combinations of its inertias that torques
/// determine) from its torques alone, within 1 % of the truth's (‖Δβ‖ / ‖β‖): the data are
/// exact and the midpoint reading of a transition is off by O(Δt²) (≈ 1e-4 of the terms at
/// the simulator's Δt), so what remains is the optimiser's distance from the minimum; a
/// wrong sign or a missing term in the residual leaves them tens of per cent off, as they
/// start.
#[test]
fn the_torque_loss_identifies_a_urdf_robots_base_parameters() {
    let t = urdf_pendulum();
    let Template::Urdf(u) = &t else {
        unreachable!()
    };
    let (learned, truth) = identify(&t, Objective::TORQUE, 300);
    let e = base_error(u, &learned, &truth);
    assert!(e <= 1e-2, "‖Δβ‖/‖β‖ = {e:.2e}");
}

/// ‖β(p) − β(truth)‖ / ‖β(truth)‖ over the robot's base parameters.
pub(super) fn base_error(u: &UrdfTemplate, p: &[f64], truth: &[f64]) -> f64 {
    let beta = |p: &[f64]| -> Vec<f64> {
        u.base_parameters(p, true)
            .into_iter()
            .map(|(_, v)| v)
            .collect()
    };
    let (b, b_true) = (beta(p), beta(truth));
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let diff: Vec<f64> = b.iter().zip(&b_true).map(|(a, b)| a - b).collect();
    let e = norm(&diff) / norm(&b_true);
    eprintln!("β {b:?}\ntruth {b_true:?}\n‖Δβ‖/‖β‖ = {e:.2e}");
    e
}

/// A state loss with a torque term trains and reports finite losses.
#[test]
fn a_mixed_loss_trains() {
    let mixed = Objective {
        step: 1.0,
        torque: 0.1,
    };
    let (learned, _) = identify(&Template::DoublePendulum, mixed, 2);
    assert!(learned.iter().all(|v| v.is_finite()), "{learned:?}");
}

#[test]
fn what_cannot_form_a_torque_is_refused_naming_the_loss() {
    let t = Template::DoublePendulum;
    let train = data(&t, 32, 4);
    let naive = ModelSpec::named("naive", Some(t.clone())).unwrap();
    let with = |loss| TrainConfig { loss, ..quick(1) };
    let refused = |spec: &ModelSpec, loss| {
        let e = Trainer::new("x", spec.clone(), &[], &train, None, with(loss), &flex())
            .err()
            .expect("refused");
        assert!(
            matches!(&e, Error::Invalid { field, .. } if field == "training.loss"),
            "{e}"
        );
    };
    refused(&naive, Objective::TORQUE);
    let wb = ModelSpec::named("W-B", Some(t.clone())).unwrap();
    for bad in [(0.0, 0.0), (-1.0, 1.0), (1.0, f64::NAN)] {
        refused(
            &wb,
            Objective {
                step: bad.0,
                torque: bad.1,
            },
        );
    }
    // Its JSON forms, and the command line's.
    let parse = |s: &str| serde_json::from_str::<TrainConfig>(s).map(|c| c.loss);
    assert_eq!(parse(r#"{"loss":"torque"}"#).unwrap(), Objective::TORQUE);
    assert_eq!(parse("{}").unwrap(), Objective::STEP);
    let w = parse(r#"{"loss":{"step":1,"torque":0.5}}"#).unwrap();
    assert_eq!((w.step, w.torque), (1.0, 0.5));
    let e = parse(r#"{"loss":{"stp":1}}"#).unwrap_err().to_string();
    assert!(e.contains("stp"), "{e}");
    assert_eq!(Objective::parse("step=0,torque=2").unwrap().torque, 2.0);
    assert!(Objective::parse("torque=x").is_err());
    // Files leave the default out and keep any other.
    let json = serde_json::to_string(&TrainConfig::default()).unwrap();
    assert!(!json.contains("loss"), "{json}");
    let c = TrainConfig {
        loss: Objective::TORQUE,
        ..TrainConfig::default()
    };
    let back: TrainConfig = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
    assert_eq!(back.loss, Objective::TORQUE);
}

/// The classic least-squares identification alone (no gradient step), from the same
/// exact data and values 30 % off: the base parameters within 1e-3 (the midpoint reading's
/// O(Δt²) is all that separates them), the rest of π where it started; with rotors, their
/// armatures are base parameters too (the first joint's summed with its rod's inertia about
/// the axis, which the world-fixed axis makes one).
#[test]
fn least_squares_alone_gives_the_base_parameters() {
    least_squares_alone(urdf_pendulum());
    least_squares_alone(pendulum_with_rotors());
}

fn least_squares_alone(t: Template) {
    let Template::Urdf(u) = &t else {
        unreachable!()
    };
    let truth = t.defaults();
    let start: Vec<f64> = truth.iter().map(|v| 1.3 * v).collect();
    let ds = data(&t, 512, 3);
    let rows = graybox::train::objective::torque_rows(&ds, &t.space(), 0);
    let ls = u
        .least_squares(&start, true, (&rows, 0), &|| false)
        .unwrap();
    let e = base_error(u, &ls.physical, &truth);
    eprintln!(
        "rank {}, projected {:?}, ‖Δβ‖/‖β‖ = {e:.2e}",
        ls.rank, ls.projected
    );
    assert!(e <= 1e-3, "‖Δβ‖/‖β‖ = {e:.2e}");
    assert!(base_error(u, &start, &truth) > 0.1, "the start is far");
    // The rods' inertias are on the boundary of physical ones (a thin rod's moment along
    // itself is zero), where the minimizer's undetermined components may step out: the
    // projection brings them back, and the template takes them as they are.
    assert!(
        t.raw_from_physical(&ls.physical).is_ok(),
        "{:?}",
        ls.projected
    );
}

/// Effort offsets are columns of the least squares too (the gains stay where they start):
/// on exact data simulated with offsets of 3 and −2 N·m, they come back within 0.05 N·m
/// (measured 0.002 and 0.02: the rods' gravity torques are ~50 N·m and the midpoint reading is
/// off by up to ~1e-3 of them, not zero on average; a sign or a column in the wrong row is off
/// by the offset itself), the base parameters within 1e-3.
#[test]
fn least_squares_finds_the_effort_offsets() {
    let text = std::fs::read_to_string(common::urdf::fixture_path("double_pendulum", "urdf"));
    let doc = serde_json::json!({"kind": "urdf", "urdf": text.unwrap(),
                                 "effort_gain": true, "effort_offset": true});
    let t = Template::from_document(&doc).unwrap();
    let Template::Urdf(u) = &t else {
        unreachable!()
    };
    let mut truth = t.defaults();
    let k = truth.len();
    (truth[k - 2], truth[k - 1]) = (3.0, -2.0);
    let config = SimConfig {
        count: 512,
        seed: 3,
        ..SimConfig::default()
    };
    let ds = simulate(&t, truth.clone(), &config).unwrap();
    let rows = graybox::train::objective::torque_rows(&ds, &t.space(), 0);
    let mut start: Vec<f64> = truth.iter().map(|v| 1.3 * v).collect();
    (start[k - 4], start[k - 3], start[k - 2], start[k - 1]) = (1.0, 1.0, 0.0, 0.0);
    let ls = u
        .least_squares(&start, true, (&rows, 0), &|| false)
        .unwrap();
    let got = &ls.physical[k - 4..];
    assert_eq!(&got[..2], [1.0, 1.0], "the gains stay");
    assert!(
        (got[2] - 3.0).abs() < 0.05 && (got[3] + 2.0).abs() < 0.05,
        "{got:?}"
    );
    assert!(base_error(u, &ls.physical, &truth) <= 1e-3);
}

/// A run that starts from the least-squares solution is at the truth's base parameters
/// after a few epochs of the torque loss at a learning rate that suits a start this close
/// (Adam's first steps move every value by about the rate), where one from the given values
/// is far (above).
#[test]
fn a_least_squares_start_trains_from_the_solution() {
    let t = urdf_pendulum();
    let Template::Urdf(u) = &t else {
        unreachable!()
    };
    let (learned, truth) = identify_with(&t, Objective::TORQUE, 3, (1e-4, true));
    let e = base_error(u, &learned, &truth);
    assert!(e <= 2e-3, "‖Δβ‖/‖β‖ = {e:.2e}");
    // Only a robot's M makes torques linear in its inertias.
    let spec = ModelSpec::named("W-B", Some(Template::DoublePendulum)).unwrap();
    let cfg = TrainConfig {
        least_squares: true,
        ..quick(1)
    };
    let ds = data(&Template::DoublePendulum, 32, 1);
    let e = Trainer::new("x", spec, &[], &ds, None, cfg, &flex())
        .err()
        .unwrap();
    assert!(
        matches!(&e, Error::Invalid { field, .. } if field == "training.least_squares"),
        "{e}"
    );
}

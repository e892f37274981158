//! The particle rollout (`infer::particles`) against each member's own rollout, computed here
//! one particle at a time: particle p follows member p mod K, under the inputs or under a
//! policy applied to its own state; each step's mean, spread, mean input and z are those of
//! the particles; a state that leaves the finite numbers names its step.

use std::path::{Path, PathBuf};

use graybox_core::control::policy::Policy;
use graybox_core::error::Error;
use graybox_core::infer::Evaluator;
use graybox_core::infer::particles::{ParticleTrack, advance, particle_rollout};
use graybox_core::model::file::ModelFile;
use graybox_core::model::report::Spread;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn load(path: &str) -> Evaluator {
    let bytes = std::fs::read(root().join(path)).unwrap();
    Evaluator::from_file(&ModelFile::from_bytes(&bytes).unwrap()).unwrap()
}

/// Deterministic inputs within ±amp: enough to move the pendulum, no random crate needed.
fn inputs(steps: usize, m: usize, amp: f64) -> Vec<f64> {
    (0..steps * m)
        .map(|i| amp * ((i as f64) * 0.7).sin())
        .collect()
}

/// Each particle's states `[T+1, 2n]` and inputs `[T, m]`, one particle and one step at a
/// time on its member alone.
fn each_particle(
    eval: &Evaluator,
    x0: &[f64],
    count: usize,
    steps: usize,
    input: &dyn Fn(usize, &[f64]) -> Vec<f64>,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let nx = x0.len();
    (0..count)
        .map(|p| {
            let member = eval.member(p % eval.member_count());
            let (mut xs, mut us) = (x0.to_vec(), vec![]);
            for t in 0..steps {
                let x = xs[t * nx..].to_vec();
                let u = input(t, &x);
                xs.extend(member.predict(&x, &u, false).0);
                us.extend(u);
            }
            (xs, us)
        })
        .collect()
}

/// The track the particles' own rollouts make: per row the mean and spread of their states,
/// per step the mean input and the largest z.
fn expected(eval: &Evaluator, each: &[(Vec<f64>, Vec<f64>)], nx: usize) -> ParticleTrack {
    let m = eval.config.m;
    let steps = each[0].1.len() / m.max(1);
    let mut track = ParticleTrack::default();
    for t in 0..=steps {
        let states: Vec<f64> = (each.iter())
            .flat_map(|(xs, _)| xs[t * nx..(t + 1) * nx].to_vec())
            .collect();
        track.push_states(&states, nx);
        if t == steps {
            break;
        }
        let us: Vec<f64> = (each.iter())
            .flat_map(|(_, us)| us[t * m..(t + 1) * m].to_vec())
            .collect();
        for j in 0..m {
            let column: Vec<f64> = us.iter().skip(j).step_by(m).copied().collect();
            track.u.push(Spread::of(&column).mean);
        }
        let z = eval.max_abs_z(&states, &us);
        track.max_abs_z.push(z.into_iter().fold(0.0, f64::max));
    }
    track
}

/// The largest difference relative to the largest magnitude (1 below it).
fn rel(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len());
    let scale = want.iter().fold(1.0_f64, |a, v| a.max(v.abs()));
    let diff = (got.iter().zip(want)).fold(0.0_f64, |a, (g, w)| a.max((g - w).abs()));
    diff / scale
}

/// A step of several states runs as one batch of columns, a particle alone as scalars: the
/// same operations in the same order per state, so they agree to the last bits (a measured
/// difference of 0 here); 1e-12 allows the compiler's different vectorisation of the two.
const BATCH_VS_ALONE: f64 = 1e-12;

fn close(got: &ParticleTrack, want: &ParticleTrack, what: &str) {
    for (g, w, field) in [
        (&got.mean, &want.mean, "mean"),
        (&got.std, &want.std, "std"),
        (&got.u, &want.u, "u"),
        (&got.max_abs_z, &want.max_abs_z, "max_abs_z"),
    ] {
        let r = rel(g, w);
        assert!(
            r <= BATCH_VS_ALONE,
            "{what} {field}: relative difference {r:e}"
        );
    }
}

#[test]
fn particles_follow_the_members_round_robin_under_inputs() {
    let eval = load("tests/fixtures/compat/wb-x3.gbx");
    assert_eq!(eval.member_count(), 3);
    let (nx, m, steps) = (eval.config.nx(), eval.config.m, 20);
    let x0 = [0.3, -0.6, 1.0, -0.5];
    let u = inputs(steps, m, 20.0);
    let input = |t: usize, _: &[f64]| u[t * m..(t + 1) * m].to_vec();
    let got = particle_rollout(&eval, &x0, 6, (steps, eval.config.dt), input, &|| false).unwrap();
    let want = expected(&eval, &each_particle(&eval, &x0, 6, steps, &input), nx);
    close(&got, &want, "six particles");
    assert_eq!((got.mean.len(), got.u.len()), ((steps + 1) * nx, steps * m));
    // The members differ, so the particles spread out; at x0 they agree.
    assert!(got.std[..nx].iter().all(|s| *s == 0.0));
    assert!(
        got.std[steps * nx..].iter().all(|s| *s > 0.0),
        "{:?}",
        got.std
    );
}

#[test]
fn a_policy_applies_to_each_particles_own_state() {
    let eval = load("tests/fixtures/compat/wb-x3.gbx");
    let (nx, m, steps) = (eval.config.nx(), eval.config.m, 15);
    let x0 = [0.2, 0.1, 0.0, 0.0];
    // A proportional-derivative pull toward the origin around zero nominal inputs.
    let k: Vec<f64> = (0..steps)
        .flat_map(|_| [5.0, 0.0, 1.0, 0.0, 0.0, 5.0, 0.0, 1.0])
        .collect();
    let policy = Policy {
        xbar: vec![0.0; (steps + 1) * nx],
        ubar: vec![0.0; steps * m],
        k,
        space: eval.config.space.clone(),
        m,
    };
    let input = |t: usize, x: &[f64]| policy.input(t, x);
    let got = particle_rollout(&eval, &x0, 5, (steps, eval.config.dt), input, &|| false).unwrap();
    let each = each_particle(&eval, &x0, 5, steps, &input);
    close(&got, &expected(&eval, &each, nx), "a policy");
    // Particles in different states are given different inputs.
    let last: Vec<f64> = each.iter().map(|(_, us)| us[(steps - 1) * m]).collect();
    assert!(Spread::of(&last).std > 0.0, "{last:?}");
}

#[test]
fn a_single_models_particles_are_its_own_rollout_with_no_spread() {
    let eval = load("tests/fixtures/inference/dp-mvf.gbx");
    let (nx, m, steps) = (eval.config.nx(), eval.config.m, 10);
    let x0 = [0.3, -0.6, 1.0, -0.5];
    let u = inputs(steps, m, 1.0);
    let input = |t: usize, _: &[f64]| u[t * m..(t + 1) * m].to_vec();
    let mut alone = x0.to_vec();
    eval.rollout(&x0, (steps, eval.config.dt), input, |x, _| {
        alone.extend_from_slice(x);
        true
    });
    let got = particle_rollout(&eval, &x0, 4, (steps, eval.config.dt), input, &|| false).unwrap();
    assert!(rel(&got.mean, &alone) <= BATCH_VS_ALONE);
    // Four equal values average to themselves within a rounding of their sum.
    let scale = alone.iter().fold(1.0_f64, |a, v| a.max(v.abs()));
    assert!(got.std.iter().all(|s| *s <= 1e-15 * scale), "{:?}", got.std);
    assert_eq!(got.mean.len(), (steps + 1) * nx);
}

#[test]
fn a_state_that_leaves_the_finite_numbers_names_its_step() {
    let eval = load("tests/fixtures/compat/wb-x3.gbx");
    let (nx, m) = (eval.config.nx(), eval.config.m);
    // Ordinary inputs for five steps, then one no model can follow.
    let input = |t: usize, _: &[f64]| vec![if t == 5 { 1e300 } else { 1.0 }; m];
    let err =
        particle_rollout(&eval, &[0.0; 4], 3, (10, eval.config.dt), input, &|| false).unwrap_err();
    assert!(err.to_string().contains("non-finite at step 6"), "{err}");
    // The steps before it are kept, and the states are where they left the particles.
    let (mut states, mut track) = (vec![0.0; 3 * nx], ParticleTrack::default());
    let err = advance(
        &eval,
        &mut states,
        0,
        (10, eval.config.dt),
        input,
        &mut track,
        &|| false,
    )
    .unwrap_err();
    assert!(err.to_string().contains("at step 6"), "{err}");
    assert_eq!((track.max_abs_z.len(), track.mean.len()), (5, 5 * nx));
    assert!(states.iter().all(|v| v.is_finite()));
    assert_eq!(&track.mean[4 * nx..], &expected_mean(&states, nx)[..]);
}

fn expected_mean(states: &[f64], nx: usize) -> Vec<f64> {
    let mut t = ParticleTrack::default();
    t.push_states(states, nx);
    t.mean
}

#[test]
fn a_caller_stops_it_and_bad_arguments_are_named() {
    let eval = load("tests/fixtures/compat/wb-x3.gbx");
    let m = eval.config.m;
    let input = |_: usize, _: &[f64]| vec![0.0; m];
    let stopped = particle_rollout(&eval, &[0.0; 4], 3, (10, eval.config.dt), input, &|| true);
    assert!(matches!(stopped, Err(Error::Cancelled)), "{stopped:?}");
    for bad in [0, 1025] {
        let err = particle_rollout(&eval, &[0.0; 4], bad, (10, eval.config.dt), input, &|| {
            false
        })
        .unwrap_err();
        assert!(err.to_string().starts_with("particles:"), "{err}");
    }
    let err =
        particle_rollout(&eval, &[0.0; 3], 3, (10, eval.config.dt), input, &|| false).unwrap_err();
    assert!(err.to_string().starts_with("x0:"), "{err}");
}

#[test]
fn a_whole_particle_rollouts_cost_names_the_argument_to_cut() {
    let eval = load("tests/fixtures/compat/wb-x3.gbx");
    let many_steps = eval.particle_rollout_cost(1_000_000, 4, false);
    assert_eq!(many_steps.field, "u");
    // The answer alone: every state's mean and spread, every step's mean input and z.
    assert!(many_steps.memory_bytes >= 8 * 1_000_000 * (2 * 4 + 2 + 1));
    assert_eq!(
        eval.particle_rollout_cost(1_000_000, 4, true).field,
        "policy"
    );
    let many_particles = eval.particle_rollout_cost(10, 1024, false);
    assert_eq!(many_particles.field, "particles");
    assert!(many_particles.memory_bytes > eval.particle_rollout_cost(10, 1, false).memory_bytes);
}

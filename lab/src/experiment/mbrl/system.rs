//! The true system and what runs on it: the random first episode, TVLQR tracking of a plan,
//! the noisy exploration, the transitions they yield and the score of an evaluation. The
//! reference (the plan on the true model) and every episode go through this same code, so
//! that their scores compare.

use serde::{Deserialize, Serialize};

use super::{DT, EXPLORATION_STD, HORIZON, MbrlSettings, Planner, Reference, STATE_BOUND, U_MAX};
use graybox::control::plan::Plan;
use graybox::control::policy::Policy;
use graybox::control::tvlqr::Gains;
use graybox::data::Dataset;
use graybox::error::Result;
use graybox::infer::Evaluator;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::templates::Template;
use graybox::rng::Rng;

/// An episode's plan and what became of it on the system, with the measures of why the two
/// part: the model's error along the plan, the plan's defects on the true system and on the
/// model, and an ensemble's spread.
///
/// A system that left the finite numbers leaves NaN and ∞ here, which JSON writes as null:
/// every value reads null back as NaN, so that such an episode's record still reads back.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Detail {
    /// The plan's states `[T+1, 4]` and the system's under TVLQR (f32: they are drawn, and
    /// every episode's are committed).
    #[serde(deserialize_with = "null_as_nan::many")]
    pub nominal: Vec<f32>,
    #[serde(deserialize_with = "null_as_nan::many")]
    pub achieved: Vec<f32>,
    /// RMS over the plan's steps of ‖f_model(x̄_t, ū_t) − f_true(x̄_t, ū_t)‖ (rad, rad/s
    /// together): how wrong the model is where it planned.
    #[serde(deserialize_with = "null_as_nan::one")]
    pub model_error: f64,
    /// The largest ‖f_true(x̄_t, ū_t) − x̄_{t+1}‖: how far the plan is from one the system can
    /// follow step by step.
    #[serde(deserialize_with = "null_as_nan::one")]
    pub true_defect: f64,
    /// The plan's constraint violation on the model (DIRCOL's defects, 0 for iLQR).
    #[serde(deserialize_with = "null_as_nan::one")]
    pub plan_defect: f64,
    /// The members' mean state standard deviation along the plan (an ensemble's).
    pub spread: Option<f64>,
}

mod null_as_nan {
    use serde::{Deserialize, Deserializer};

    pub fn one<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    pub fn many<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
        let v = Vec::<Option<f32>>::deserialize(d)?;
        Ok(v.into_iter().map(|x| x.unwrap_or(f32::NAN)).collect())
    }
}

impl Detail {
    pub(super) fn of(sys: &Evaluator, learned: &Evaluator, p: &Plan, achieved: &[f64]) -> Self {
        let (mut sq, mut defect) = (0.0, 0.0f64);
        for t in 0..HORIZON {
            let (x, u) = (&p.x[4 * t..4 * t + 4], &p.u[2 * t..2 * t + 2]);
            let truth = sys.step(x, u);
            sq += dist2(&learned.step(x, u), &truth);
            defect = defect.max(dist2(&truth, &p.x[4 * t + 4..4 * t + 8]).sqrt());
        }
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect();
        Self {
            nominal: f32s(&p.x),
            achieved: f32s(achieved),
            model_error: (sq / HORIZON as f64).sqrt(),
            true_defect: defect,
            plan_defect: p.constraint_violation,
            spread: (p.x_std.as_ref()).map(|s| s.iter().sum::<f64>() / s.len().max(1) as f64),
        }
    }
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum()
}

/// The system: the true double pendulum at Δt = 0.1.
pub(super) fn system() -> Result<Evaluator> {
    let t = Template::DoublePendulum;
    Evaluator::from_file(&ModelFile::from_template(
        &t,
        &t.defaults(),
        DT,
        Integrator::Rk4,
    )?)
}

/// The pipeline on the true model with either planner, the better score kept: "solved" is
/// measured against the best the pipeline does with the true dynamics (a learned model once
/// beat the iLQR plan on the true one).
pub(super) fn reference(s: &MbrlSettings, sys: &Evaluator) -> Result<Reference> {
    let mut best: Option<Reference> = None;
    for planner in [Planner::Dircol, Planner::Ilqr] {
        let p = sys.plan(&s.request(planner, 0), &|| false)?;
        let states = track(sys, &p.x, &p.u, &p.gains);
        let r = Reference {
            score: score(&states),
            plan_cost: p.cost,
            converged: p.converged,
            planner: planner.name().to_string(),
        };
        if best.as_ref().is_none_or(|b| r.score < b.score) {
            best = Some(r);
        }
    }
    Ok(best.expect("two planners ran"))
}

/// The first episode, the same for every model of a seed: u ~ N(0, 120²) clipped to ±120.
pub(super) fn random_episode(sys: &Evaluator, seed: u64) -> Dataset {
    random_inputs(sys, &mut Rng::derive(seed, 0x0000_5EED))
}

pub(super) fn random_inputs(sys: &Evaluator, rng: &mut Rng) -> Dataset {
    let u: Vec<f64> = (0..2 * HORIZON)
        .map(|_| (U_MAX * rng.normal()).clamp(-U_MAX, U_MAX))
        .collect();
    let mut x = vec![0.0; 4];
    let mut states = x.clone();
    for t in 0..HORIZON {
        x = sys.step(&x, &u[2 * t..2 * t + 2]);
        states.extend_from_slice(&x);
    }
    transitions(&states, &u)
}

/// The exploration episode: the plan with N(0, 0.25²) added to every nominal state and input,
/// tracked on the system with TVLQR gains of the learned model along the noisy nominal.
pub(super) fn explore(
    sys: &Evaluator,
    learned: &Evaluator,
    s: &MbrlSettings,
    p: &Plan,
    rng: &mut Rng,
) -> Dataset {
    let mut noise = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .map(|x| x + EXPLORATION_STD * rng.normal())
            .collect()
    };
    let xbar = noise(&p.x);
    let ubar = noise(&p.u);
    let [q, r, qf] = s.weights();
    // A noisy nominal can leave the region where the model is finite; the plan's own gains
    // then still track it.
    let gains = learned
        .tvlqr(&xbar, &ubar, &q, &r, &qf)
        .unwrap_or_else(|_| p.gains.clone());
    let states = track(sys, &xbar, &ubar, &gains);
    let inputs = applied_inputs(&states, &xbar, &ubar, &gains);
    transitions(&states, &inputs)
}

fn policy(xbar: &[f64], ubar: &[f64], gains: &Gains) -> Policy {
    Policy {
        xbar: xbar.to_vec(),
        ubar: ubar.to_vec(),
        k: gains
            .k
            .iter()
            .flat_map(|k| k.data.iter().copied())
            .collect(),
        space: graybox::physics::space::Space::flat(2, &[]),
        m: 2,
    }
}

fn clip(u: Vec<f64>) -> Vec<f64> {
    u.into_iter().map(|v| v.clamp(-U_MAX, U_MAX)).collect()
}

/// States `[T+1, 4]` of the system under u_t = clip(ū_t − K_t (x_t − x̄_t)) from rest.
pub(super) fn track(sys: &Evaluator, xbar: &[f64], ubar: &[f64], gains: &Gains) -> Vec<f64> {
    let pol = policy(xbar, ubar, gains);
    let mut states = vec![0.0; 4];
    sys.rollout(
        &[0.0; 4],
        (HORIZON, sys.config.dt),
        |t, x| clip(pol.input(t, x)),
        |x, _| {
            states.extend_from_slice(x);
            true
        },
    );
    states
}

/// The inputs `track` applied along `states`.
fn applied_inputs(states: &[f64], xbar: &[f64], ubar: &[f64], gains: &Gains) -> Vec<f64> {
    let pol = policy(xbar, ubar, gains);
    (0..HORIZON)
        .flat_map(|t| clip(pol.input(t, &states[4 * t..4 * t + 4])))
        .collect()
}

/// Transitions of a trajectory, up to its first state outside `STATE_BOUND` (or not finite).
fn transitions(states: &[f64], u: &[f64]) -> Dataset {
    let mut a: [Vec<f64>; 5] = Default::default();
    for t in 0..HORIZON {
        let (x, y) = (&states[4 * t..4 * t + 4], &states[4 * t + 4..4 * t + 8]);
        let sane = y.iter().all(|v| v.abs() <= STATE_BOUND)
            && u[2 * t..2 * t + 2].iter().all(|v| v.is_finite());
        if !sane {
            break;
        }
        a[0].extend_from_slice(&x[..2]);
        a[1].extend_from_slice(&x[2..]);
        a[2].extend_from_slice(&u[2 * t..2 * t + 2]);
        a[3].extend_from_slice(&y[..2]);
        a[4].extend_from_slice(&y[2..]);
    }
    let [q, qdot, u, q_next, qdot_next] = a;
    Dataset {
        dt: DT,
        nq: 2,
        nv: 2,
        m: 2,
        q,
        qdot,
        u,
        q_next,
        qdot_next,
        trajectories: None,
        steps: None,
    }
}

/// Mean distance of the end effector p = (l1 sin q1 + l2 sin(q1+q2), −l1 cos q1 − l2 cos(q1+q2))
/// to the upright point (0, l1 + l2) over the states (docs/control.md#upright-score); ∞ if a state is not finite.
pub(super) fn score(states: &[f64]) -> f64 {
    let t = Template::DoublePendulum;
    let v = t.defaults();
    let l = |name: &str| v[t.index_of(name).expect("double pendulum lengths")];
    let (l1, l2) = (l("l1"), l("l2"));
    let d: Vec<f64> = states
        .chunks(4)
        .map(|x| {
            let (q1, q2) = (x[0], x[1]);
            let px = l1 * q1.sin() + l2 * (q1 + q2).sin();
            let py = -l1 * q1.cos() - l2 * (q1 + q2).cos();
            (px * px + (py - l1 - l2).powi(2)).sqrt()
        })
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    if mean.is_finite() {
        mean
    } else {
        f64::INFINITY
    }
}

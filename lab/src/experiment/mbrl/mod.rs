//! `graybox-lab experiment mbrl`: the paper's §V-D. Model-based RL of the double pendulum's
//! swing-up: plan on the learned model (`control::plan`), track the plan with TVLQR on the
//! system, add the episode to the data, train on, repeat.
//!
//! The system is the true template as a model (Δt = 0.1, RK4): `Plan`, `Linearize` and the
//! rollouts all use one map. The planner is direct collocation, as the paper's (`--planner
//! dircol`, the default), or iLQR on the same cost (`--planner ilqr`,
//! docs/control.md#swing-up-task-and-cost). A model written `MVB×5` (or `MVBx5`) is an
//! ensemble of 5 MVB members, each trained on its own bootstrap resample of the data, and
//! planned on as `--ensemble-cost` says.

mod args;
mod episode;
mod plots;
mod report;
mod system;

use std::path::PathBuf;

use clap::Args;
use serde::{Deserialize, Serialize};

use super::out::OutDir;
use super::pool::{self, Progress};
use super::{model_seeds, seeds_arg};
use graybox::control::linalg::Mat;
use graybox::control::plan::PlanRequest;
use graybox::error::Result;

use args::{PlanCost, Planner, learning_rate, loop_models};
use episode::run_one;
use report::report;
use system::{reference, system};

const DT: f64 = 0.1;
/// 2.6 s: the paper's swing-up in 2.06 s and the hold for 0.5 s.
const HORIZON: usize = 26;
const U_MAX: f64 = 120.0;
const EXPLORATION_STD: f64 = 0.25;
/// The paper's Adam learning rate.
const LR: f64 = 3e-4;
/// The cost's weights: Q on every step, Q_f = 1000 Q on the last state, R on the inputs.
const Q: [f64; 4] = [1.0, 1.0, 0.1, 0.1];
const QF_SCALE: f64 = 1000.0;
const R: f64 = 1e-4;
/// "Solved": within this factor of the reference score.
const SOLVED: f64 = 1.1;
/// Transitions are kept while every state component stays within this (rad, rad/s): RK4 at
/// Δt = 0.1 on a pendulum spun up past this leaves the physical solution (and then f32), and
/// one such transition makes a model's loss overflow. 5× the paper's training velocities; no
/// state of a stored run before the bound existed came near it.
const STATE_BOUND: f64 = 50.0;

#[derive(Args, Debug)]
pub struct MbrlArgs {
    /// Directory for results.md, results.csv, mbrl.png, run.json and the runs' states;
    /// running again with the same settings continues every run after its last episode.
    #[arg(long)]
    pub out: PathBuf,
    /// Models, comma-separated; `MVB×5` or `MVBx5` is an ensemble of 5 [default:
    /// naive,MVF,MVB; MVB with --quick].
    #[arg(long)]
    pub models: Option<String>,
    /// Seeds 0..N [default: 3; 1 with --quick].
    #[arg(long)]
    pub seeds: Option<u64>,
    /// Episodes after the random one [default: 30; 2 with --quick].
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Epochs on the random episode [default: 5000; 100 with --quick].
    #[arg(long)]
    pub initial_epochs: Option<usize>,
    /// Epochs after each episode [default: 1000; 20 with --quick].
    #[arg(long)]
    pub episode_epochs: Option<usize>,
    /// Extra randomised initial guesses per plan (the best plan is kept) [default: 8; 1 with
    /// --quick].
    #[arg(long)]
    pub restarts: Option<usize>,
    /// Iterations per start (iLQR's, or DIRCOL's SQP) [default: 200; 30 with --quick].
    #[arg(long)]
    pub max_iterations: Option<usize>,
    /// Adam's learning rate, for every training of the loop [default: 3e-4, the paper's].
    #[arg(long)]
    pub lr: Option<f64>,
    /// Mark both angles periodic: every network sees (sin q, cos q) for q, and the loss's
    /// position term is blind to whole turns (README "Periodic coordinates"). Not the
    /// paper's: a change tried against its failures.
    #[arg(long)]
    pub periodic: bool,
    /// The planner on the learned models.
    #[arg(long, value_enum, default_value_t = Planner::Dircol)]
    pub planner: Planner,
    /// What a plan on an ensemble minimizes.
    #[arg(long, value_enum, default_value_t = PlanCost::MeanDynamics)]
    pub ensemble_cost: PlanCost,
    #[command(flatten)]
    pub run: pool::RunArgs,
}

#[derive(Debug, Clone, Serialize)]
struct MbrlSettings {
    system: &'static str,
    models: Vec<String>,
    seeds: Vec<u64>,
    episodes: usize,
    horizon: usize,
    u_max: f64,
    initial_epochs: usize,
    episode_epochs: usize,
    lr: f64,
    /// Only when set (so that runs without it keep their settings).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    periodic: bool,
    batch: &'static str,
    q: [f64; 4],
    qf: [f64; 4],
    r: [f64; 2],
    planner: Planner,
    /// Only when a model is an ensemble (so that runs without one keep their settings).
    #[serde(skip_serializing_if = "Option::is_none")]
    ensemble: Option<EnsembleSettings>,
    restarts: usize,
    max_iterations: usize,
    exploration_std: f64,
    state_bound: f64,
    solved_within: f64,
    backend: &'static str,
    precision: &'static str,
}

#[derive(Debug, Clone, Serialize)]
struct EnsembleSettings {
    cost: PlanCost,
    /// Each member trains on its own bootstrap resample of the data.
    bootstrap: bool,
}

impl MbrlSettings {
    fn from_args(a: &MbrlArgs) -> Result<Self> {
        let q = a.run.quick;
        let default: &[&str] = if q {
            &["MVB"]
        } else {
            &["naive", "MVF", "MVB"]
        };
        let models = loop_models(a.models.as_deref(), default)?;
        let any_ensemble = models.iter().any(|m| m.contains('×'));
        let seeds = seeds_arg(a.seeds, if q { 1 } else { 3 })?;
        Ok(Self {
            system: "double_pendulum (paper values) as a white-box model, dt 0.1, RK4; from (0,0,0,0) to (pi,0,0,0)",
            models,
            seeds,
            episodes: a.episodes.unwrap_or(if q { 2 } else { 30 }),
            horizon: HORIZON,
            u_max: U_MAX,
            initial_epochs: a
                .initial_epochs
                .unwrap_or(if q { 100 } else { 5000 })
                .max(1),
            episode_epochs: a.episode_epochs.unwrap_or(if q { 20 } else { 1000 }).max(1),
            lr: learning_rate(a.lr)?,
            periodic: a.periodic,
            batch: "full",
            q: Q,
            qf: Q.map(|v| QF_SCALE * v),
            r: [R; 2],
            planner: a.planner,
            ensemble: any_ensemble.then_some(EnsembleSettings {
                cost: a.ensemble_cost,
                bootstrap: true,
            }),
            restarts: a.restarts.unwrap_or(if q { 1 } else { 8 }),
            max_iterations: a.max_iterations.unwrap_or(if q { 30 } else { 200 }).max(1),
            exploration_std: EXPLORATION_STD,
            state_bound: STATE_BOUND,
            solved_within: SOLVED,
            backend: "flex",
            precision: "f32",
        })
    }

    /// The cost's weights Q, R, Q_f.
    fn weights(&self) -> [Mat; 3] {
        [Mat::diag(&self.q), Mat::diag(&self.r), Mat::diag(&self.qf)]
    }

    /// The swing-up's plan request for `planner`.
    fn request(&self, planner: Planner, seed: u64) -> PlanRequest {
        let goal = vec![std::f64::consts::PI, 0.0, 0.0, 0.0];
        PlanRequest {
            method: planner.method(),
            u_min: Some(vec![-U_MAX; 2]),
            u_max: Some(vec![U_MAX; 2]),
            max_iterations: self.max_iterations,
            restarts: self.restarts,
            seed,
            ensemble_cost: self
                .ensemble
                .as_ref()
                .map_or_else(Default::default, |e| e.cost.of()),
            ..PlanRequest::new(vec![0.0; 4], goal, HORIZON, self.weights())
        }
    }
}

/// One episode of one run: the noise-free evaluation of the plan made on the model.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Episode {
    model: String,
    seed: u64,
    episode: usize,
    /// Mean distance of the end effector to the upright point over the evaluation rollout (m);
    /// ∞ when the system's state left the finite numbers (stored as null: JSON has no ∞).
    #[serde(with = "infinite_as_null")]
    score: f64,
    /// The plan's cost on the model, and whether iLQR converged.
    plan_cost: Option<f64>,
    converged: bool,
    /// Transitions the model had been trained on when it planned.
    data_size: usize,
    /// Training loss after the episode's training; none when that training diverged.
    train_loss: Option<f64>,
    seconds: f64,
    /// Of `seconds`: the plan on the learned model, and the training after the episode (none
    /// in records from before they were measured).
    #[serde(default)]
    plan_seconds: Option<f64>,
    #[serde(default)]
    train_seconds: Option<f64>,
    /// Why the plan failed, when it did (the episode then explores with random inputs).
    error: Option<String>,
    /// The plan and what became of it on the system, when there was a plan.
    #[serde(default)]
    detail: Option<system::Detail>,
}

/// A score that may be ∞ in JSON: null stands for it.
mod infinite_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// The reference: the pipeline on the true model, with the planner that scored best there.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Reference {
    score: f64,
    plan_cost: f64,
    converged: bool,
    planner: String,
}

pub fn run(a: MbrlArgs) -> Result<()> {
    let s = MbrlSettings::from_args(&a)?;
    let out = OutDir::open(&a.out, "mbrl", &s)?;
    let sys = system()?;
    let reference = match out.get::<Reference>("reference") {
        Some(r) => r,
        None => {
            let r = reference(&s, &sys)?;
            out.put("reference", &r)?;
            r
        }
    };
    eprintln!(
        "reference score (plan on the true model, {}): {:.4} m",
        reference.planner, reference.score
    );
    let runs = model_seeds(&s.models, &s.seeds);
    let progress = Progress::new(runs.len() * s.episodes, 0);
    let results = pool::parallel(
        &runs,
        pool::threads(a.run.jobs),
        &progress,
        |(m, seed), status| run_one(&s, &out, &sys, m, *seed, &progress, status),
    );
    progress.finish();
    let episodes: Vec<Episode> = results.into_iter().collect::<Result<Vec<_>>>()?.concat();
    report(&s, &out, &reference, &episodes)?;
    out.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An episode whose system left the finite numbers scores ∞ and has NaN and ∞ in its
    /// detail; its record must read back (JSON writes both as null, and a record that does
    /// not read back stops the resume).
    #[test]
    fn an_infinite_score_survives_its_record() {
        let ep = Episode {
            model: "MVB".into(),
            seed: 1,
            episode: 7,
            score: f64::INFINITY,
            plan_cost: Some(1.0),
            converged: true,
            data_size: 182,
            train_loss: Some(2.0),
            seconds: 3.0,
            plan_seconds: None,
            train_seconds: None,
            error: None,
            detail: None,
        };
        let json = serde_json::to_value(&ep).unwrap();
        assert!(json["score"].is_null());
        let back: Episode = serde_json::from_value(json).unwrap();
        assert_eq!(back.score, f64::INFINITY);
        let finite: Episode = serde_json::from_value(
            serde_json::to_value(Episode {
                score: 1.5,
                ..ep.clone()
            })
            .unwrap(),
        )
        .unwrap();
        assert_eq!(finite.score, 1.5);
        // And so must the plan's detail, the achieved states gone to ∞ and NaN with it.
        let detail = system::Detail {
            nominal: vec![0.0, 1.0],
            achieved: vec![f32::INFINITY, f32::NAN, 2.0],
            model_error: f64::NAN,
            true_defect: f64::INFINITY,
            plan_defect: 0.5,
            spread: None,
        };
        let json = serde_json::to_value(Episode {
            detail: Some(detail),
            ..ep
        })
        .unwrap();
        let back: Episode = serde_json::from_value(json).unwrap();
        let d = back.detail.unwrap();
        assert!(d.achieved[0].is_nan() && d.achieved[1].is_nan() && d.achieved[2] == 2.0);
        assert!(d.model_error.is_nan() && d.true_defect.is_nan() && d.plan_defect == 0.5);
    }
}

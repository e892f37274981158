//! `graybox experiment mbrl`: the paper's §V-D. Model-based RL of the double pendulum's
//! swing-up: plan on the learned model (`control::plan`), track the plan with TVLQR on the
//! system, add the episode to the data, train on, repeat.
//!
//! The system is the true template as a model (Δt = 0.1, RK4): `Plan`, `Linearize` and the
//! rollouts all use one map. The paper plans with direct collocation; graybox plans with iLQR
//! on the same cost at every step (design.md §8).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};

use super::csv_line;
use super::out::OutDir;
use super::plot::{self, COLORS};
use super::pool::{self, Progress, Status};
use crate::backend::{self, Backend, Precision};
use crate::control::linalg::Mat;
use crate::control::plan::{Plan, PlanRequest, plan};
use crate::control::policy::Policy;
use crate::control::tvlqr::Gains;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::infer::Evaluator;
use crate::model::file::{ModelFile, write_atomic};
use crate::model::spec::ModelSpec;
use crate::physics::integrator::Integrator;
use crate::physics::templates::Template;
use crate::rng::Rng;
use crate::train::{TrainConfig, TrainState, Trainer};

const DT: f64 = 0.1;
/// 2.6 s: the paper's swing-up in 2.06 s and the hold for 0.5 s.
const HORIZON: usize = 26;
const U_MAX: f64 = 120.0;
const EXPLORATION_STD: f64 = 0.25;
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
    /// Models, comma-separated [default: naive,MVF,MVB; MVB with --quick].
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
    /// iLQR iterations per start [default: 200; 30 with --quick].
    #[arg(long)]
    pub max_iterations: Option<usize>,
    #[command(flatten)]
    pub run: pool::RunArgs,
}

#[derive(Debug, Clone, Serialize)]
struct Settings {
    system: &'static str,
    models: Vec<String>,
    seeds: Vec<u64>,
    episodes: usize,
    horizon: usize,
    u_max: f64,
    initial_epochs: usize,
    episode_epochs: usize,
    lr: f64,
    batch: &'static str,
    q: [f64; 4],
    qf: [f64; 4],
    r: [f64; 2],
    restarts: usize,
    max_iterations: usize,
    exploration_std: f64,
    state_bound: f64,
    solved_within: f64,
    backend: &'static str,
    precision: &'static str,
}

impl Settings {
    fn from_args(a: &MbrlArgs) -> Result<Self> {
        let q = a.run.quick;
        let models: Vec<String> = match &a.models {
            Some(m) => m
                .split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty())
                .collect(),
            None if q => vec!["MVB".into()],
            None => ["naive", "MVF", "MVB"].map(String::from).to_vec(),
        };
        if models.is_empty() {
            return Err(Error::invalid("models", "name at least one model"));
        }
        for m in &models {
            ModelSpec::named(m, Some(Template::DoublePendulum))
                .map_err(|e| Error::invalid("models", e.to_string()))?;
        }
        let seeds = a.seeds.unwrap_or(if q { 1 } else { 3 });
        if seeds == 0 {
            return Err(Error::invalid("seeds", "must be at least 1"));
        }
        Ok(Self {
            system: "double_pendulum (paper values) as a white-box model, dt 0.1, RK4; from (0,0,0,0) to (pi,0,0,0)",
            models,
            seeds: (0..seeds).collect(),
            episodes: a.episodes.unwrap_or(if q { 2 } else { 30 }),
            horizon: HORIZON,
            u_max: U_MAX,
            initial_epochs: a
                .initial_epochs
                .unwrap_or(if q { 100 } else { 5000 })
                .max(1),
            episode_epochs: a.episode_epochs.unwrap_or(if q { 20 } else { 1000 }).max(1),
            lr: LR,
            batch: "full",
            q: Q,
            qf: Q.map(|v| QF_SCALE * v),
            r: [R; 2],
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

    fn request(&self, seed: u64) -> PlanRequest {
        let goal = vec![std::f64::consts::PI, 0.0, 0.0, 0.0];
        PlanRequest {
            u_min: Some(vec![-U_MAX; 2]),
            u_max: Some(vec![U_MAX; 2]),
            max_iterations: self.max_iterations,
            restarts: self.restarts,
            seed,
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
    /// Why the plan failed, when it did (the episode then explores with random inputs).
    error: Option<String>,
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

/// What a run needs to continue after its last finished episode.
#[derive(Serialize, Deserialize)]
struct RunState {
    episodes_done: usize,
    checkpoint: TrainState,
    /// The transitions so far: q, q̇, u, q′, q̇′ (row-major).
    data: [Vec<f64>; 5],
}

/// The reference: the pipeline on the true model.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Reference {
    score: f64,
    plan_cost: f64,
    converged: bool,
}

/// The system: the true double pendulum at Δt = 0.1.
fn system() -> Result<Evaluator> {
    let t = Template::DoublePendulum;
    Evaluator::from_file(&ModelFile::from_template(
        &t,
        &t.defaults(),
        DT,
        Integrator::Rk4,
    )?)
}

pub fn run(a: MbrlArgs) -> Result<()> {
    let s = Settings::from_args(&a)?;
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
        "reference score (plan on the true model): {:.4} m",
        reference.score
    );
    let runs: Vec<(String, u64)> = s
        .models
        .iter()
        .flat_map(|m| s.seeds.iter().map(move |&seed| (m.clone(), seed)))
        .collect();
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
    out.finish()?;
    eprintln!(
        "wrote {} ({:.0} s of wall time over every invocation)",
        out.path("results.md").display(),
        out.wall_seconds()
    );
    Ok(())
}

fn reference(s: &Settings, sys: &Evaluator) -> Result<Reference> {
    let p = plan(sys, &s.request(0), &|| false)?;
    let states = track(sys, &p.x, &p.u, &p.gains);
    Ok(Reference {
        score: score(&states),
        plan_cost: p.cost,
        converged: p.converged,
    })
}

/// One model and seed through every episode, continuing from its saved state.
fn run_one(
    s: &Settings,
    out: &OutDir,
    sys: &Evaluator,
    model: &str,
    seed: u64,
    progress: &Progress,
    status: &Status,
) -> Result<Vec<Episode>> {
    let state_path = out.path(&format!("state-{model}-seed{seed}.json"));
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let (mut trainer, mut data, done) = match std::fs::read(&state_path) {
        Ok(bytes) => {
            let st: RunState = serde_json::from_slice(&bytes)
                .map_err(|e| Error::corrupt(state_path.display().to_string(), e))?;
            let data = Dataset::new(DT, 2, 2, st.data)?;
            let trainer = Trainer::resume(st.checkpoint, &data, None, &device)?;
            (trainer, data, st.episodes_done)
        }
        Err(_) => {
            let data = random_episode(sys, seed);
            status.show(&format!(
                "{model} seed {seed}: training on the random episode"
            ));
            let cfg = TrainConfig {
                epochs: s.initial_epochs,
                batch_size: data.count(),
                lr: s.lr,
                val_fraction: 0.0,
                seed,
                ..TrainConfig::default()
            };
            let spec = ModelSpec::named(model, Some(Template::DoublePendulum))?;
            let mut trainer = Trainer::new(model, spec, &[], &data, None, cfg, &device)?;
            train(
                &mut trainer,
                status,
                &format!("{model} seed {seed}, random episode"),
            )?;
            save_state(&state_path, &trainer, &data, 0)?;
            (trainer, data, 0)
        }
    };
    let mut episodes = vec![];
    for e in 1..=s.episodes {
        let key = format!("{model}/seed{seed}/episode{e}");
        if e <= done {
            let ep = out.get::<Episode>(&key).ok_or_else(|| {
                Error::corrupt(
                    key.clone(),
                    "the run's state is past this episode but its record is missing",
                )
            })?;
            progress.cells_done(1, &format!("{key}: done earlier"));
            episodes.push(ep);
            continue;
        }
        let start = Instant::now();
        let what = format!("{model} seed {seed} episode {e}");
        status.show(&format!("{what}: planning"));
        let learned = Evaluator::from_file(&trainer.model_file())?;
        let (before, planned_on) = (trainer.checkpoint(), data.count());
        let planned = plan(
            &learned,
            &s.request(seed.wrapping_mul(1000) + e as u64),
            &|| false,
        );
        let mut rng = Rng::derive(seed, 0xE915_0DE0 + e as u64);
        let (score_now, explored, plan_cost, converged, error) = match &planned {
            Ok(p) => {
                let eval = track(sys, &p.x, &p.u, &p.gains);
                let explored = explore(sys, &learned, s, p, &mut rng);
                (score(&eval), explored, Some(p.cost), p.converged, None)
            }
            Err(err) => {
                let still = vec![0.0; 4 * (HORIZON + 1)];
                (
                    score(&still),
                    random_inputs(sys, &mut rng),
                    None,
                    false,
                    Some(err.to_string()),
                )
            }
        };
        let (loss, error) = match train_on(&mut trainer, &data, &explored, s, status, &what) {
            Ok((more, loss)) => {
                data = more;
                (Some(loss), error)
            }
            // A diverged training must not end the other runs: the episode keeps the model
            // and the data from before it, and says why.
            Err(err) => {
                trainer = Trainer::resume(before, &data, None, &device)?;
                let why = format!("training diverged, the episode's transitions dropped: {err}");
                let error = match error {
                    Some(plan_error) => format!("{plan_error}; {why}"),
                    None => why,
                };
                (None, Some(error))
            }
        };
        let ep = Episode {
            model: model.to_string(),
            seed,
            episode: e,
            score: score_now,
            plan_cost,
            converged,
            data_size: planned_on,
            train_loss: loss,
            seconds: start.elapsed().as_secs_f64(),
            error,
        };
        // The record first, then the state: a kill between the two repeats the episode, which
        // computes the same numbers again.
        out.put(&key, &ep)?;
        save_state(&state_path, &trainer, &data, e)?;
        progress.cells_done(
            1,
            &format!("{key}: score {score_now:.3} m ({:.0} s)", ep.seconds),
        );
        episodes.push(ep);
    }
    Ok(episodes)
}

/// Trains `epochs` more on the data with the episode's transitions; that data and the loss.
fn train_on(
    trainer: &mut Trainer,
    data: &Dataset,
    explored: &Dataset,
    s: &Settings,
    status: &Status,
    what: &str,
) -> Result<(Dataset, f64)> {
    let more = append(data, explored)?;
    trainer.extend(&more, s.episode_epochs, more.count())?;
    let loss = train(trainer, status, what)?;
    Ok((more, loss))
}

/// Trains to the trainer's epoch target, showing progress; the last training loss.
fn train(trainer: &mut Trainer, status: &Status, what: &str) -> Result<f64> {
    let mut last = f64::NAN;
    trainer.run(&AtomicBool::new(false), |m, _| {
        last = m.train_loss;
        if m.epoch % 50 == 0 {
            status.show(&format!(
                "{what}: epoch {} loss {:.3e}",
                m.epoch, m.train_loss
            ));
        }
    })?;
    Ok(last)
}

fn save_state(
    path: &std::path::Path,
    trainer: &Trainer,
    data: &Dataset,
    done: usize,
) -> Result<()> {
    // The per-epoch history is most of a checkpoint and the experiment reads none of it: the
    // states are committed with the results, so they stay small.
    let mut checkpoint = trainer.checkpoint();
    checkpoint.history.clear();
    let st = RunState {
        episodes_done: done,
        checkpoint,
        data: [
            data.q.clone(),
            data.qdot.clone(),
            data.u.clone(),
            data.q_next.clone(),
            data.qdot_next.clone(),
        ],
    };
    write_atomic(
        path,
        &serde_json::to_vec(&st).expect("run state serializes"),
    )
}

/// The first episode, the same for every model of a seed: u ~ N(0, 120²) clipped to ±120.
fn random_episode(sys: &Evaluator, seed: u64) -> Dataset {
    random_inputs(sys, &mut Rng::derive(seed, 0x0000_5EED))
}

fn random_inputs(sys: &Evaluator, rng: &mut Rng) -> Dataset {
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
fn explore(sys: &Evaluator, learned: &Evaluator, s: &Settings, p: &Plan, rng: &mut Rng) -> Dataset {
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
        nx: 4,
        m: 2,
    }
}

fn clip(u: Vec<f64>) -> Vec<f64> {
    u.into_iter().map(|v| v.clamp(-U_MAX, U_MAX)).collect()
}

/// States `[T+1, 4]` of the system under u_t = clip(ū_t − K_t (x_t − x̄_t)) from rest.
fn track(sys: &Evaluator, xbar: &[f64], ubar: &[f64], gains: &Gains) -> Vec<f64> {
    let pol = policy(xbar, ubar, gains);
    let mut states = vec![0.0; 4];
    sys.rollout(
        &[0.0; 4],
        HORIZON,
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
        n: 2,
        m: 2,
        q,
        qdot,
        u,
        q_next,
        qdot_next,
    }
}

fn append(data: &Dataset, more: &Dataset) -> Result<Dataset> {
    let cat = |a: &[f64], b: &[f64]| [a, b].concat();
    Dataset::new(
        DT,
        2,
        2,
        [
            cat(&data.q, &more.q),
            cat(&data.qdot, &more.qdot),
            cat(&data.u, &more.u),
            cat(&data.q_next, &more.q_next),
            cat(&data.qdot_next, &more.qdot_next),
        ],
    )
}

/// Mean distance of the end effector p = (l1 sin q1 + l2 sin(q1+q2), −l1 cos q1 − l2 cos(q1+q2))
/// to the upright point (0, l1 + l2) over the states (design.md §8); ∞ if a state is not finite.
fn score(states: &[f64]) -> f64 {
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

fn report(s: &Settings, out: &OutDir, reference: &Reference, eps: &[Episode]) -> Result<()> {
    let mut csv = String::from(
        "model,seed,episode,score,data_size,plan_cost,converged,train_loss,seconds,error\n",
    );
    for e in eps {
        csv += &csv_line(&[
            e.model.clone(),
            e.seed.to_string(),
            e.episode.to_string(),
            format!("{:.6}", e.score),
            e.data_size.to_string(),
            e.plan_cost.map_or_else(String::new, |c| format!("{c:.6e}")),
            e.converged.to_string(),
            e.train_loss.map_or(String::new(), |l| format!("{l:.6e}")),
            format!("{:.1}", e.seconds),
            e.error.clone().unwrap_or_default(),
        ]);
    }
    out.write("results.csv", csv.as_bytes())?;
    let target = SOLVED * reference.score;
    let mut md = String::from("# Model-based RL of the swing-up (paper §V-D)\n\n");
    md += &format!(
        "Score: mean distance (m) of the end effector to the upright point over the noise-free \
         evaluation rollout (lower is better). Reference, the same pipeline planned on the true \
         model: **{:.4} m**. Solved: score ≤ {SOLVED} × reference = {target:.4} m. Q = diag{:?}, \
         R = {R}·I, Q_f = {QF_SCALE}·Q, |u| ≤ {U_MAX}, horizon {HORIZON} × {DT} s, {} restarts.\n\n",
        reference.score, s.q, s.restarts
    );
    md += "| model | seed | first episode within 10% | best score | last score |\n|---|---|---|---|---|\n";
    for m in &s.models {
        for &seed in &s.seeds {
            let run: Vec<&Episode> = eps
                .iter()
                .filter(|e| &e.model == m && e.seed == seed)
                .collect();
            let first = run.iter().find(|e| e.score <= target).map_or_else(
                || format!("not within {}", s.episodes),
                |e| e.episode.to_string(),
            );
            let best = run.iter().map(|e| e.score).fold(f64::INFINITY, f64::min);
            let last = run.last().map_or(f64::NAN, |e| e.score);
            md += &format!("| {m} | {seed} | {first} | {best:.4} | {last:.4} |\n");
        }
    }
    md += "\n![score per episode](mbrl.png)\n";
    out.write("results.md", md.as_bytes())?;
    plot_scores(s, out, reference, eps)
}

/// Score per episode: per model the mean over seeds (line) and the range (band), with the
/// reference line.
fn plot_scores(s: &Settings, out: &OutDir, reference: &Reference, eps: &[Episode]) -> Result<()> {
    let finite_max = eps
        .iter()
        .map(|e| e.score)
        .filter(|v| v.is_finite())
        .fold(reference.score, f64::max);
    let top = finite_max * 1.1;
    plot::png(&out.path("mbrl.png"), (900, 520), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "Model-based RL: score per episode (mean over seeds, band: range)",
                plot::font(20),
            )
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5f64..(s.episodes as f64 + 0.5), 0f64..top)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_desc("episode")
            .x_labels(s.episodes.min(15))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc("mean end-effector distance to upright (m)")
            .label_style(plot::font(14))
            .axis_desc_style(plot::font(15))
            .draw()?;
        for (i, m) in s.models.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let mut mean = vec![];
            let mut band_lo = vec![];
            let mut band_hi = vec![];
            for e in 1..=s.episodes {
                let v: Vec<f64> = eps
                    .iter()
                    .filter(|x| &x.model == m && x.episode == e)
                    .map(|x| x.score.min(top))
                    .collect();
                if v.is_empty() {
                    continue;
                }
                let x = e as f64;
                mean.push((x, v.iter().sum::<f64>() / v.len() as f64));
                band_lo.push((x, v.iter().copied().fold(f64::INFINITY, f64::min)));
                band_hi.push((x, v.iter().copied().fold(0.0, f64::max)));
            }
            let band: Vec<(f64, f64)> = band_hi
                .iter()
                .copied()
                .chain(band_lo.iter().rev().copied())
                .collect();
            chart.draw_series([Polygon::new(band, color.mix(0.2).filled())])?;
            chart
                .draw_series(LineSeries::new(mean, color.stroke_width(2)))?
                .label(m.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        chart
            .draw_series(LineSeries::new(
                [
                    (0.5, reference.score),
                    (s.episodes as f64 + 0.5, reference.score),
                ],
                BLACK.stroke_width(1),
            ))?
            .label("reference (true model)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(1)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(plot::font(14))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An episode whose system left the finite numbers scores ∞; its record must read back
    /// (JSON writes ∞ as null, and a record that does not read back stops the resume).
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
            error: None,
        };
        let json = serde_json::to_value(&ep).unwrap();
        assert!(json["score"].is_null());
        let back: Episode = serde_json::from_value(json).unwrap();
        assert_eq!(back.score, f64::INFINITY);
        let finite: Episode =
            serde_json::from_value(serde_json::to_value(Episode { score: 1.5, ..ep }).unwrap())
                .unwrap();
        assert_eq!(finite.score, 1.5);
    }
}

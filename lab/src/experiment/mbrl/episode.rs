//! A run: one model and seed through its episodes (plan on the learned model, explore on the
//! system, train on the grown data). A run saves its state after every episode, so that the
//! experiment, stopped at any point, continues each run where it stopped; a training that
//! diverges ends only its episode, not the other runs. A single model is an ensemble of one
//! member, which trains exactly as a lone model does.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::args::loop_model;
use super::system::{Detail, explore, random_episode, random_inputs, score, track};
use super::{DT, Episode, HORIZON, MbrlSettings};
use crate::experiment::out::OutDir;
use crate::experiment::pool::{Progress, Status};
use graybox::backend::{self, Backend, Precision};
use graybox::data::Dataset;
use graybox::error::{Error, Result};
use graybox::infer::Evaluator;
use graybox::model::file::write_atomic;
use graybox::model::spec::ModelSpec;
use graybox::physics::templates::Template;
use graybox::rng::Rng;
use graybox::train::ensemble::Ensemble;
use graybox::train::{TrainConfig, TrainState};

/// What a run needs to continue after its last finished episode.
#[derive(Serialize, Deserialize)]
struct RunState {
    episodes_done: usize,
    checkpoint: Members,
    /// The transitions so far: q, q̇, u, q′, q̇′ (row-major).
    data: [Vec<f64>; 5],
}

/// The members' states; a lone model's written as its one state (as runs before ensembles).
#[derive(Serialize, Deserialize)]
#[serde(untagged)]
enum Members {
    One(Box<TrainState>),
    Many(Vec<TrainState>),
}

impl Members {
    fn of(mut states: Vec<TrainState>) -> Self {
        // The per-epoch history is most of a checkpoint and the experiment reads none of it:
        // the states are committed with the results, so they stay small.
        states.iter_mut().for_each(|s| s.history.clear());
        match <[TrainState; 1]>::try_from(states) {
            Ok([one]) => Members::One(Box::new(one)),
            Err(many) => Members::Many(many),
        }
    }

    fn into_vec(self) -> Vec<TrainState> {
        match self {
            Members::One(one) => vec![*one],
            Members::Many(many) => many,
        }
    }
}

/// How long the run's first training took (`{model}/seed{seed}/initial`).
#[derive(Serialize, Deserialize)]
pub(super) struct Initial {
    pub(super) seconds: f64,
}

/// One model and seed through every episode, continuing from its saved state.
pub(super) fn run_one(
    s: &MbrlSettings,
    out: &OutDir,
    sys: &Evaluator,
    model: &str,
    seed: u64,
    progress: &Progress,
    status: &Status,
) -> Result<Vec<Episode>> {
    let file = model.replace('×', "x");
    let state_path = out.path(&format!("state-{file}-seed{seed}.json"));
    let device = backend::device(Backend::Flex, Precision::F32)?.autodiff();
    let (mut trainer, mut data, done) = match std::fs::read(&state_path) {
        Ok(bytes) => {
            let st: RunState = serde_json::from_slice(&bytes)
                .map_err(|e| Error::corrupt(state_path.display().to_string(), e))?;
            let data = Dataset::new(DT, (2, 2), 2, st.data)?;
            let states = st.checkpoint.into_vec();
            let trainer = Ensemble::resume_states(states, &data, None, &device)?;
            (trainer, data, st.episodes_done)
        }
        Err(_) => {
            let start = Instant::now();
            let data = random_episode(sys, seed);
            status.show(&format!(
                "{model} seed {seed}: training on the random episode"
            ));
            let (base, members) = loop_model(model)?;
            let cfg = TrainConfig {
                epochs: s.initial_epochs,
                batch_size: data.count(),
                lr: s.lr,
                val_fraction: 0.0,
                seed,
                ensemble: members,
                periodic: if s.periodic { vec![true; 2] } else { vec![] },
                ..TrainConfig::default()
            };
            let spec = ModelSpec::named(base, Some(Template::DoublePendulum))?;
            let mut trainer = Ensemble::new(base, spec, &[], &data, None, cfg, &device)?;
            train(
                &mut trainer,
                status,
                &format!("{model} seed {seed}, random episode"),
            )?;
            let seconds = start.elapsed().as_secs_f64();
            out.put(&format!("{model}/seed{seed}/initial"), &Initial { seconds })?;
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
        let (before, planned_on) = (trainer.states(), data.count());
        let request = s.request(s.planner, seed.wrapping_mul(1000) + e as u64);
        let plan_start = Instant::now();
        let planned = learned.plan(&request, &|| false);
        let plan_seconds = plan_start.elapsed().as_secs_f64();
        let mut rng = Rng::derive(seed, 0xE915_0DE0 + e as u64);
        let (score_now, explored, plan_cost, converged, error, detail) = match &planned {
            Ok(p) => {
                let eval = track(sys, &p.x, &p.u, &p.gains);
                let explored = explore(sys, &learned, s, p, &mut rng);
                let detail = Detail::of(sys, &learned, p, &eval);
                let cost = Some(p.cost);
                (
                    score(&eval),
                    explored,
                    cost,
                    p.converged,
                    None,
                    Some(detail),
                )
            }
            Err(err) => {
                let still = vec![0.0; 4 * (HORIZON + 1)];
                let explored = random_inputs(sys, &mut rng);
                let error = Some(err.to_string());
                (score(&still), explored, None, false, error, None)
            }
        };
        let train_start = Instant::now();
        let trained = train_on(&mut trainer, &data, &explored, s, status, &what);
        let train_seconds = train_start.elapsed().as_secs_f64();
        let (loss, error) = match trained {
            Ok((more, loss)) => {
                data = more;
                (Some(loss), error)
            }
            // A diverged training must not end the other runs: the episode keeps the model
            // and the data from before it, and says why.
            Err(err) => {
                trainer = Ensemble::resume_states(before, &data, None, &device)?;
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
            plan_seconds: Some(plan_seconds),
            train_seconds: Some(train_seconds),
            error,
            detail,
        };
        // The record first, then the state: a kill between the two repeats the episode, which
        // computes the same numbers again.
        out.put(&key, &ep)?;
        crate::experiment::out::killed_after(&key);
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
    trainer: &mut Ensemble,
    data: &Dataset,
    explored: &Dataset,
    s: &MbrlSettings,
    status: &Status,
    what: &str,
) -> Result<(Dataset, f64)> {
    let more = append(data, explored)?;
    trainer.extend(&more, s.episode_epochs, more.count())?;
    let loss = train(trainer, status, what)?;
    Ok((more, loss))
}

/// Trains to the trainer's epoch target, showing progress; the last training loss (the
/// members' mean).
fn train(trainer: &mut Ensemble, status: &Status, what: &str) -> Result<f64> {
    let mut last = f64::NAN;
    let never = AtomicBool::new(false);
    while !trainer.finished() {
        let m = trainer.run_epoch(&never)?.mean;
        last = m.train_loss;
        if m.epoch % 50 == 0 {
            status.show(&format!(
                "{what}: epoch {} loss {:.3e}",
                m.epoch, m.train_loss
            ));
        }
    }
    Ok(last)
}

fn save_state(
    path: &std::path::Path,
    trainer: &Ensemble,
    data: &Dataset,
    done: usize,
) -> Result<()> {
    let st = RunState {
        episodes_done: done,
        checkpoint: Members::of(trainer.states()),
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

fn append(data: &Dataset, more: &Dataset) -> Result<Dataset> {
    let cat = |a: &[f64], b: &[f64]| [a, b].concat();
    Dataset::new(
        DT,
        (2, 2),
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

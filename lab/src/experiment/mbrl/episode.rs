//! A run: one model and seed through its episodes (plan on the learned model, explore on the
//! system, train on the grown data). A run saves its state after every episode, so that the
//! experiment, stopped at any point, continues each run where it stopped; a training that
//! diverges ends only its episode, not the other runs.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::system::{explore, random_episode, random_inputs, score, track};
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
use graybox::train::{TrainConfig, TrainState, Trainer};

/// What a run needs to continue after its last finished episode.
#[derive(Serialize, Deserialize)]
struct RunState {
    episodes_done: usize,
    checkpoint: TrainState,
    /// The transitions so far: q, q̇, u, q′, q̇′ (row-major).
    data: [Vec<f64>; 5],
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
        let request = s.request(s.planner, seed.wrapping_mul(1000) + e as u64);
        let planned = learned.plan(&request, &|| false);
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
    s: &MbrlSettings,
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

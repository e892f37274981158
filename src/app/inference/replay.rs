//! A model replaying a recorded trajectory (the dashboard's "rollout vs data"): from the
//! trajectory's first state with its recorded inputs, the model's states beside the recorded
//! ones, T + 1 of each; with particles, an ensemble's spread along it too.

use serde::Serialize;

use super::{Class, Cost};
use crate::app::App;
use crate::data::Dataset;
use crate::data::trajectories::{self, Segment};
use crate::error::{Error, Result};
use crate::infer::particles::{self, ParticleTrack};

/// One trajectory's q and q̇ per time step, `[T+1][n]` each.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Series {
    pub q: Vec<Vec<f64>>,
    pub qdot: Vec<Vec<f64>>,
}

/// GET /v1/models/{id}/rollout: the recorded trajectory and the model's replay of it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Replay {
    pub model_id: String,
    pub dataset_id: String,
    pub index: usize,
    pub dt: f64,
    /// Seconds from the trajectory's first state, T + 1 values.
    pub t: Vec<f64>,
    pub recorded: Series,
    pub predicted: Series,
    /// The recorded inputs the model was driven with, T rows of m.
    pub u: Vec<Vec<f64>>,
    /// With `particles`: the same replay as a particle rollout (Rollout's: particle p follows
    /// member p mod K), the particles' mean and standard deviation at each state. `predicted`
    /// stays the mean dynamics'.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub particles: Option<ParticleSeries>,
}

/// A particle replay's mean and spread, up to T + 1 rows of each: fewer when a particle's
/// state left the finite numbers (the rows before it).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ParticleSeries {
    pub count: usize,
    pub mean: Series,
    pub std: Series,
}

/// A dataset's trajectories and where their boundaries come from.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct TrajectoryList {
    /// `uploaded` (trajectory form) or `chained` (flat rows whose next state is the next
    /// row's state exactly).
    pub source: String,
    pub count: usize,
    #[schema(value_type = Vec<Object>)]
    pub items: Vec<TrajectoryItem>,
    pub next_page_token: Option<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct TrajectoryItem {
    pub index: usize,
    /// Its first row in the dataset.
    pub start: usize,
    /// Transitions (T); the trajectory has T + 1 states.
    pub length: usize,
}

impl App {
    /// Every trajectory of a dataset (404 when there is none); `loaded` is its arrays when
    /// the caller has them already (chains are found in them).
    async fn segments(
        &self,
        dataset_id: &str,
        loaded: Option<&Dataset>,
    ) -> Result<(Vec<Segment>, &'static str)> {
        let not_found = || Error::NotFound(format!("dataset {dataset_id}"));
        let stored = self.store.dataset_trajectories(dataset_id).await?;
        match (stored.ok_or_else(not_found)?, loaded) {
            (Some(lengths), _) => Ok((trajectories::from_lengths(&lengths), "uploaded")),
            (None, Some(ds)) => Ok((trajectories::chains(ds), "chained")),
            (None, None) => {
                let ds = self
                    .store
                    .load_dataset(dataset_id)
                    .await?
                    .ok_or_else(not_found)?;
                Ok((trajectories::chains(&ds), "chained"))
            }
        }
    }

    /// GET /v1/datasets/{id}/trajectories: a page of them, in order.
    pub async fn dataset_trajectories(
        &self,
        dataset_id: &str,
        size: Option<i64>,
        token: Option<&str>,
    ) -> Result<TrajectoryList> {
        let size = super::super::paging::size(size)? as usize;
        let from = super::super::paging::decode("trajectories", token)?.unwrap_or(0) as usize;
        let (all, source) = self.segments(dataset_id, None).await?;
        let items: Vec<TrajectoryItem> = all
            .iter()
            .skip(from)
            .take(size)
            .map(|s| TrajectoryItem {
                index: s.index,
                start: s.start,
                length: s.length,
            })
            .collect();
        let next = (from + items.len() < all.len())
            .then(|| super::super::paging::encode("trajectories", (from + items.len()) as i64));
        Ok(TrajectoryList {
            source: source.into(),
            count: all.len(),
            items,
            next_page_token: next,
        })
    }

    /// The model's replay of trajectory `index` of a dataset. Every check that needs no
    /// rows comes first; the dataset is read under the memory budget (shared with the other
    /// requests reading it), and only the trajectory's rows are kept for the rollout.
    pub async fn replay(
        &self,
        model_id: &str,
        dataset_id: &str,
        index: usize,
        particles: Option<usize>,
    ) -> Result<Replay> {
        if let Some(p) = particles {
            particles::check_particles(p)?;
        }
        let eval = self.evaluator(model_id).await?;
        let (nx, m) = (eval.config.nx(), eval.config.m);
        let info = self.dataset_for_model(dataset_id, &eval.config).await?;
        // Uploaded boundaries are known without the rows; chains are found in them.
        let uploaded = self.store.dataset_trajectories(dataset_id).await?.flatten();
        let mut loaded = None;
        let segments = match uploaded {
            Some(lengths) => trajectories::from_lengths(&lengths),
            None => {
                let read = self.read_dataset(&info).await?;
                let chains = trajectories::chains(read.ds());
                loaded = Some(read);
                chains
            }
        };
        let seg = self.replayable(&segments, dataset_id, index, (nx, m), particles)?;
        let loaded = match loaded {
            Some(read) => read,
            None => self.read_dataset(&info).await?,
        };
        let (recorded, inputs) = recorded_segment(loaded.ds(), seg);
        let ds = loaded.ds();
        let steps: Vec<f64> = (seg.start..seg.start + seg.length)
            .map(|i| ds.step(i))
            .collect();
        drop(loaded);
        let mut t = vec![0.0];
        t.extend(steps.iter().scan(0.0, |c, d| {
            *c += d;
            Some(*c)
        }));
        let u = inputs.chunks(m).map(<[f64]>::to_vec).collect();
        // No deadline on REST; the replay stops when its caller goes away.
        let replayed = self
            .heavy_until(Class::Long, "replay", None, move |stop| {
                let inputs = (&inputs[..], &steps[..]);
                let spread = match particles {
                    Some(p) => Some(particle_replay(&eval, &recorded, inputs, p, stop)?),
                    None => None,
                };
                let (recorded, predicted) = replay_segment(&eval, recorded, inputs, stop)?;
                Some((recorded, predicted, spread))
            })
            .await?;
        Ok(Replay {
            model_id: model_id.into(),
            dataset_id: dataset_id.into(),
            index,
            dt: info.dt,
            t,
            recorded: replayed.0,
            predicted: replayed.1,
            u,
            particles: replayed.2,
        })
    }

    /// Trajectory `index` of `segments` if it can be replayed within the limits, its cost
    /// admitted (with `particles`, their states and their mean and spread too).
    fn replayable(
        &self,
        segments: &[Segment],
        dataset_id: &str,
        index: usize,
        (nx, m): (usize, usize),
        particles: Option<usize>,
    ) -> Result<Segment> {
        let seg = *segments.get(index).ok_or_else(|| {
            Error::invalid(
                "index",
                format!(
                    "dataset {dataset_id} has {} trajectories (0-based index)",
                    segments.len()
                ),
            )
        })?;
        // Stored before uploads refused them: an empty trajectory has no state to start from.
        if seg.length == 0 {
            return Err(Error::Unprocessable {
                field: "index".into(),
                message: format!("trajectory {index} of dataset {dataset_id} is empty"),
            });
        }
        let max = self.settings.max_rollout_steps;
        if seg.length > max {
            return Err(Error::ResourceExhausted(format!(
                "trajectory {index} has {} steps, over the limit of {max} (--max-rollout-steps)",
                seg.length
            )));
        }
        let spread = if particles.is_some() { 2 * nx } else { 0 };
        let bytes = 8 * (2 * nx + m + spread) * (seg.length + 1);
        let states = 8 * nx * particles.unwrap_or(0);
        self.admit(
            "index",
            &Cost {
                response_bytes: bytes,
                memory_bytes: 2 * bytes + 3 * states,
            },
        )?;
        Ok(seg)
    }
}

/// The recorded states of `seg` (T + 1) and its inputs (T rows of m), copied out of the
/// dataset so that the rollout does not keep the whole of it.
fn recorded_segment(ds: &Dataset, seg: Segment) -> (Series, Vec<f64>) {
    let (nq, nv) = (ds.nq, ds.nv);
    let row = |a: &[f64], n: usize, i: usize| a[i * n..(i + 1) * n].to_vec();
    let rows = seg.start..seg.start + seg.length;
    let mut recorded = Series {
        q: rows.clone().map(|i| row(&ds.q, nq, i)).collect(),
        qdot: rows.clone().map(|i| row(&ds.qdot, nv, i)).collect(),
    };
    // Not empty (`replayable`): the last transition's next state ends the recording.
    let last = seg.start + seg.length - 1;
    recorded.q.push(row(&ds.q_next, nq, last));
    recorded.qdot.push(row(&ds.qdot_next, nv, last));
    let inputs = ds.u[seg.start * ds.m..(seg.start + seg.length) * ds.m].to_vec();
    (recorded, inputs)
}

/// A recording's inputs (T rows of m) and its steps' seconds (T).
type Inputs<'a> = (&'a [f64], &'a [f64]);

/// The recording and the model's replay of it from its first state with its inputs, each
/// step as long as the recording's; `None` when `stop` ended it.
fn replay_segment(
    eval: &crate::infer::Evaluator,
    recorded: Series,
    (inputs, steps): Inputs,
    stop: &dyn Fn() -> bool,
) -> Option<(Series, Series)> {
    let (nq, m) = (recorded.q[0].len(), eval.config.m);
    let mut x: Vec<f64> = [recorded.q[0].clone(), recorded.qdot[0].clone()].concat();
    let mut predicted = Series {
        q: vec![x[..nq].to_vec()],
        qdot: vec![x[nq..].to_vec()],
    };
    for (t, &dt) in steps.iter().enumerate() {
        let u = &inputs[t * m..(t + 1) * m];
        (x, _) = eval.predict_until(&x, u, dt, false, &|| false)?;
        predicted.q.push(x[..nq].to_vec());
        predicted.qdot.push(x[nq..].to_vec());
        if stop() {
            return None;
        }
    }
    Some((recorded, predicted))
}

/// The replay as `count` particles from the recording's first state under its inputs; `None`
/// when `stop` ended it.
fn particle_replay(
    eval: &crate::infer::Evaluator,
    recorded: &Series,
    (inputs, steps): Inputs,
    count: usize,
    stop: &dyn Fn() -> bool,
) -> Option<ParticleSeries> {
    let (nq, nx, m) = (eval.config.nq(), eval.config.nx(), eval.config.m);
    let x0 = [recorded.q[0].clone(), recorded.qdot[0].clone()].concat();
    let mut states = x0.repeat(count);
    let mut track = ParticleTrack::default();
    track.push_states(&states, nx);
    let input = |t: usize, _: &[f64]| inputs[t * m..(t + 1) * m].to_vec();
    // A particle's state leaving the finite numbers ends it early, and the track then holds
    // the states before: the band ends where the first particle ran away.
    for (t, &dt) in steps.iter().enumerate() {
        match particles::advance(eval, &mut states, t, (1, dt), input, &mut track, stop) {
            Err(Error::Cancelled) => return None,
            Err(_) => break,
            Ok(()) => {}
        }
    }
    let series = |rows: &[f64]| Series {
        q: rows.chunks(nx).map(|x| x[..nq].to_vec()).collect(),
        qdot: rows.chunks(nx).map(|x| x[nq..].to_vec()).collect(),
    };
    Some(ParticleSeries {
        count,
        mean: series(&track.mean),
        std: series(&track.std),
    })
}

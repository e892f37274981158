//! The prediction loss over windows of transitions (one transition each for the one-step
//! loss): the transitions kept as host arrays and gathered into tensors per batch, the mean
//! loss over a whole set (validation and the `eval` command), and a batch's loss with its
//! gradient, split into shards. Training steps, validation and `eval` share this code so that
//! they measure the same loss.

use burn::tensor::{Device, Tensor, TensorData};

use super::Trainer;
use crate::data::Dataset;
use crate::error::Result;
use crate::model::Model;
use crate::model::ModelConfig;
use crate::physics::urdf::delay::input_width;
use crate::train::objective::{Objective, torque_rows};
use crate::train::shards::{self, ParamGrads};
use crate::train::windows::Windows;

/// One set of transitions as host arrays: x = [q, v], u, target x'.
pub(super) struct HostData {
    x: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
    /// A state's width, nq + nv.
    nx: usize,
    /// Of which q's.
    nq: usize,
    m: usize,
    /// Each row's Δt_i / Δt when the transitions have steps of their own.
    scale: Option<Vec<f64>>,
    /// The loss's weights; with a torque term, each transition's row of it
    /// (`objective::torque_rows`) and that row's width.
    objective: Objective,
    torque: Option<(Vec<f64>, usize)>,
}

impl HostData {
    /// The states [q, v], `[N, nq + nv]`.
    pub(super) fn states(&self) -> &[f64] {
        &self.x
    }

    /// `ds`'s transitions for a model of step `dt`: each row's Δt_i / dt is kept when a row's
    /// step is not the model's (a log's own steps, or data at another rate).
    pub(super) fn new(ds: &Dataset, dt: f64) -> Self {
        let (x, y) = ds.states();
        let scale = (ds.steps.is_some() || ds.dt != dt)
            .then(|| (0..ds.count()).map(|i| ds.step(i) / dt).collect());
        Self {
            x,
            u: ds.u.clone(),
            y,
            nx: ds.nq + ds.nv,
            nq: ds.nq,
            m: ds.m,
            scale,
            objective: Objective::STEP,
            torque: None,
        }
    }

    /// The same data for a loss of `objective`'s weights, for a model of `config`.
    pub(super) fn with_objective(
        mut self,
        ds: &Dataset,
        config: &ModelConfig,
        o: Objective,
    ) -> Self {
        self.objective = o;
        let lags = config.effort_lags();
        let width = ds.nq + 2 * ds.nv + input_width(ds.m, lags);
        self.torque = (o.torque > 0.0).then(|| (torque_rows(ds, &config.space, lags), width));
        self
    }

    /// The first `k` rows' q.
    pub(super) fn configurations(&self, k: usize) -> Vec<Vec<f64>> {
        self.x
            .chunks(self.nx)
            .take(k)
            .map(|x| x[..self.nq].to_vec())
            .collect()
    }

    /// Rows `idx + k` of one array as a tensor.
    fn take(a: &[f64], w: usize, idx: &[usize], k: usize, device: &Device) -> Tensor<2> {
        let v: Vec<f64> = idx
            .iter()
            .flat_map(|&i| a[(i + k) * w..(i + k + 1) * w].iter().copied())
            .collect();
        Tensor::from_data(TensorData::new(v, [idx.len(), w]), device)
    }

    /// x' of rows `idx + k`'s states `x` under their inputs `u`, each transition as long as
    /// the data says.
    fn step(
        &self,
        model: &Model,
        (x, u): (Tensor<2>, Tensor<2>),
        idx: &[usize],
        k: usize,
        device: &Device,
    ) -> Tensor<2> {
        match &self.scale {
            Some(s) => model.step_scaled(x, u, Self::take(s, 1, idx, k, device)),
            None => model.step(x, u),
        }
    }

    /// Σ over the windows starting at rows `idx` of each window's loss: the objective's
    /// weights on the state loss and on the torque loss of the windows' transitions, step
    /// k's weighted by `weights[k]` in both.
    fn window_loss_sum(
        &self,
        model: &Model,
        idx: &[usize],
        weights: &[f64],
        device: &Device,
    ) -> Tensor<1> {
        let Objective { step, torque } = self.objective;
        let states = (step > 0.0).then(|| self.state_loss_sum(model, idx, weights, device));
        let torques = (self.torque.as_ref()).map(|(rows, width)| {
            let each = weights.iter().enumerate().map(|(k, w)| {
                let sum = model.torque_sum(Self::take(rows, *width, idx, k, device));
                if *w == 1.0 { sum } else { sum.mul_scalar(*w) }
            });
            each.reduce(|a, b| a + b).expect("a window has a step")
        });
        match (states, torques) {
            (Some(s), None) if step == 1.0 => s,
            (Some(s), None) => s.mul_scalar(step),
            (None, Some(t)) => t.mul_scalar(torque),
            (Some(s), Some(t)) => s.mul_scalar(step) + t.mul_scalar(torque),
            (None, None) => unreachable!("a validated objective weighs a term"),
        }
    }

    /// Σ over the windows starting at rows `idx` of each window's state loss: the model's
    /// rollout from the first state under the recorded inputs against the recorded states,
    /// step k's error weighted by `weights[k]`. Gradients flow through every step.
    fn state_loss_sum(
        &self,
        model: &Model,
        idx: &[usize],
        weights: &[f64],
        device: &Device,
    ) -> Tensor<1> {
        let x = Self::take(&self.x, self.nx, idx, 0, device);
        let step = |k: usize| {
            (
                Self::take(&self.u, self.m, idx, k, device),
                Self::take(&self.y, self.nx, idx, k, device),
            )
        };
        let advance = |x, u, k| self.step(model, (x, u), idx, k, device);
        if let ([_], None) = (weights, &self.scale) {
            // The one-step loss exactly as it always was (no weight multiplies it).
            let (u, y) = step(0);
            return model.loss_sum(x, u, y);
        }
        let mut x = x;
        let mut total: Option<Tensor<1>> = None;
        for (k, w) in weights.iter().enumerate() {
            let (u, y) = step(k);
            x = advance(x, u, k);
            let e = model.error_sum(x.clone(), y).mul_scalar(*w);
            total = Some(match total {
                None => e,
                Some(t) => t + e,
            });
        }
        total.expect("a window has at least one step")
    }
}

/// Mean loss of `model` over the `windows` of `data`, in chunks of at most 4096 rows (window
/// steps), each split into `shards` pieces run on `pool`, without autodiff.
pub(super) fn mean_loss(
    model: &Model,
    data: &HostData,
    windows: &Windows,
    shards: usize,
    pool: Option<&rayon::ThreadPool>,
) -> f64 {
    let device = model.device();
    let chunk = (4096 / windows.horizon()).max(1);
    let total: f64 = (windows.starts)
        .chunks(chunk)
        .flat_map(|c| {
            let pieces = shards::split(c, shards::piece_count(shards, c.len(), model));
            shards::map_pieces(&pieces, pool, |p| {
                scalar(data.window_loss_sum(model, p, &windows.weights, &device))
            })
        })
        .sum();
    total / windows.count() as f64
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_data().iter::<f64>().next().unwrap_or(f64::NAN)
}

/// The mean loss of a trained model on a dataset (the `eval` command).
pub fn evaluate(model: &Model, ds: &Dataset) -> Result<f64> {
    check_shape(model, ds)?;
    let one_step = Windows::one_step(ds.count());
    Ok(mean_loss(
        &model.valid(),
        &HostData::new(ds, model.config.dt),
        &one_step,
        1,
        None,
    ))
}

fn check_shape(model: &Model, ds: &Dataset) -> Result<()> {
    (model.config).check_data("data", (ds.nq(), ds.nv(), ds.m))
}

/// An ensemble on a dataset (the `eval` command): the one-step loss of the members' mean
/// prediction (what the service answers), each member's own loss, and the members' standard
/// deviation of x' per coordinate, root mean square over the rows (divisor K − 1).
#[derive(Debug, Clone)]
pub struct EnsembleEval {
    pub loss: f64,
    pub member_losses: Vec<f64>,
    pub prediction_std: Vec<f64>,
}

pub fn evaluate_members(members: &[Model], ds: &Dataset) -> Result<EnsembleEval> {
    let first = members.first().expect("an ensemble has a member");
    check_shape(first, ds)?;
    let member_losses = (members.iter())
        .map(|m| evaluate(m, ds))
        .collect::<Result<Vec<f64>>>()?;
    let models: Vec<Model> = members.iter().map(Model::valid).collect();
    let dt = first.config.dt;
    let (data, device, k) = (HostData::new(ds, dt), first.device(), members.len() as f64);
    let all: Vec<usize> = (0..ds.count()).collect();
    let (mut loss, mut ss) = (0.0, vec![0.0; data.nx]);
    for rows in all.chunks(4096) {
        let x = HostData::take(&data.x, data.nx, rows, 0, &device);
        let u = HostData::take(&data.u, data.m, rows, 0, &device);
        let each: Vec<Tensor<2>> = (models.iter())
            .map(|m| data.step(m, (x.clone(), u.clone()), rows, 0, &device))
            .collect();
        let mean = (each.iter().skip(1))
            .fold(each[0].clone(), |a, p| a + p.clone())
            .div_scalar(k);
        let y = HostData::take(&data.y, data.nx, rows, 0, &device);
        loss += scalar(models[0].error_sum(mean.clone(), y));
        for p in each {
            let d = (p - mean.clone()).square().sum_dim(0).into_data();
            ss.iter_mut()
                .zip(d.iter::<f64>())
                .for_each(|(s, v)| *s += v);
        }
    }
    let rows = ds.count() as f64;
    let prediction_std = (ss.iter())
        .map(|s| {
            if k > 1.0 {
                (s / ((k - 1.0) * rows)).sqrt()
            } else {
                0.0
            }
        })
        .collect();
    Ok(EnsembleEval {
        loss: loss / rows,
        member_losses,
        prediction_std,
    })
}

impl Trainer {
    /// The mean loss over the training windows starting at rows `batch` and its gradient (the
    /// parameters' visiting order), the batch split into shards as a training step splits it.
    pub fn loss_and_grads(&self, batch: &[usize]) -> (f64, ParamGrads) {
        let rows = batch.len() as f64;
        let k = self.shards_of(batch.len());
        let weights = &self.windows().weights;
        let shard = |idx: &[usize], model: &Model| {
            let loss = (self.data.train)
                .window_loss_sum(model, idx, weights, &model.device())
                .div_scalar(rows);
            let value = scalar(loss.clone());
            (value, shards::gradients(&model.params, &loss))
        };
        if k == 1 {
            return shard(batch, &self.model);
        }
        let results = shards::map_pieces(&shards::split(batch, k), self.pool.as_deref(), |idx| {
            let model = self
                .model
                .with_params(shards::fresh_leaves(self.model.params.clone()));
            shard(idx, &model)
        });
        let value = results.iter().map(|r| r.0).sum();
        (
            value,
            shards::sum_grads(results.into_iter().map(|r| r.1).collect()),
        )
    }
}

//! The one-step prediction loss: the transitions kept as host arrays and gathered into
//! tensors per batch, the mean loss over a whole set (validation and the `eval` command), and
//! a batch's loss with its gradient, split into shards. Training steps, validation and `eval`
//! share this code so that they measure the same loss.

use burn::tensor::{Device, Tensor, TensorData};

use super::Trainer;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::model::Model;
use crate::train::shards::{self, ParamGrads};

/// One set of transitions as host arrays: x = [q, q̇], u, target x'.
pub(super) struct HostData {
    x: Vec<f64>,
    u: Vec<f64>,
    y: Vec<f64>,
    pub(super) count: usize,
    n2: usize,
    m: usize,
}

impl HostData {
    pub(super) fn new(ds: &Dataset) -> Self {
        let (x, y) = ds.states();
        Self {
            x,
            u: ds.u.clone(),
            y,
            count: ds.count(),
            n2: 2 * ds.n,
            m: ds.m,
        }
    }

    /// The first `k` rows' q.
    pub(super) fn configurations(&self, k: usize) -> Vec<Vec<f64>> {
        let n = self.n2 / 2;
        self.x
            .chunks(self.n2)
            .take(k)
            .map(|x| x[..n].to_vec())
            .collect()
    }

    fn gather(&self, idx: &[usize], device: &Device) -> (Tensor<2>, Tensor<2>, Tensor<2>) {
        let take = |a: &[f64], w: usize| -> Tensor<2> {
            let v: Vec<f64> = idx
                .iter()
                .flat_map(|&i| a[i * w..(i + 1) * w].iter().copied())
                .collect();
            Tensor::from_data(TensorData::new(v, [idx.len(), w]), device)
        };
        (
            take(&self.x, self.n2),
            take(&self.u, self.m),
            take(&self.y, self.n2),
        )
    }
}

/// Mean loss of `model` over `data`, in chunks of at most 4096 rows, each split into
/// `shards` pieces run on `pool`, without autodiff.
pub(super) fn mean_loss(
    model: &Model,
    data: &HostData,
    shards: usize,
    pool: Option<&rayon::ThreadPool>,
) -> f64 {
    let device = model.device();
    let min_rows = shards::min_shard_rows(&model.config.spec);
    let idx: Vec<usize> = (0..data.count).collect();
    let total: f64 = idx
        .chunks(4096)
        .flat_map(|c| {
            let pieces = shards::split(c, shards::shard_count(shards, c.len(), min_rows));
            shards::map_pieces(&pieces, pool, |p| {
                let (x, u, y) = data.gather(p, &device);
                scalar(model.loss_sum(x, u, y))
            })
        })
        .sum();
    total / data.count as f64
}

fn scalar(t: Tensor<1>) -> f64 {
    t.into_data().iter::<f64>().next().unwrap_or(f64::NAN)
}

/// The mean loss of a trained model on a dataset (the `eval` command).
pub fn evaluate(model: &Model, ds: &Dataset) -> Result<f64> {
    if ds.n != model.config.n || ds.m != model.config.m {
        return Err(Error::invalid(
            "data",
            format!(
                "dataset has n = {}, m = {} but the model has n = {}, m = {}",
                ds.n, ds.m, model.config.n, model.config.m
            ),
        ));
    }
    Ok(mean_loss(&model.valid(), &HostData::new(ds), 1, None))
}

impl Trainer {
    /// The mean loss over the training rows `batch` and its gradient (the parameters' visiting
    /// order), the batch split into shards as a training step splits it.
    pub fn loss_and_grads(&self, batch: &[usize]) -> (f64, ParamGrads) {
        let rows = batch.len() as f64;
        let k = self.shards_of(batch.len());
        let shard = |idx: &[usize], model: &Model| {
            let (x, u, y) = self.train.gather(idx, &model.device());
            let loss = model.loss_sum(x, u, y).div_scalar(rows);
            let value = scalar(loss.clone());
            (value, shards::gradients(&model.params, &loss))
        };
        if k == 1 {
            return shard(batch, &self.model);
        }
        let results = shards::map_pieces(&shards::split(batch, k), self.pool.as_ref(), |idx| {
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

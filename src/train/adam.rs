//! Adam (Kingma & Ba 2015) over a module's parameters, with its state as plain arrays so that a
//! checkpoint restores it exactly.

use burn::module::{Module, ModuleMapper, Param};
use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};

use super::shards::ParamGrads;

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPS: f64 = 1e-8;

/// First and second moments per parameter tensor (flattened), in the module's visiting order.
#[derive(Debug, Clone, Default)]
pub struct Adam {
    pub step: u64,
    moments: Vec<Option<(Tensor<1>, Tensor<1>)>>,
}

/// Adam's state as plain numbers, for checkpoints.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AdamState {
    pub step: u64,
    pub moments: Vec<Option<(Vec<f64>, Vec<f64>)>>,
}

struct StepMapper<'a> {
    grads: &'a ParamGrads,
    moments: &'a mut Vec<Option<(Tensor<1>, Tensor<1>)>>,
    index: usize,
    lr: f64,
    bias1: f64,
    bias2: f64,
}

impl ModuleMapper for StepMapper<'_> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, _) = param.consume();
        let i = self.index;
        self.index += 1;
        if self.moments.len() <= i {
            self.moments.resize(i + 1, None);
        }
        let Some(g) = self.grads.get(i).cloned().flatten() else {
            return Param::initialized(id, tensor);
        };
        let dims = tensor.dims();
        let numel: usize = dims.iter().product();
        let (m, v) = match self.moments[i].take() {
            Some((m, v)) => (
                m.mul_scalar(BETA1) + g.clone().mul_scalar(1.0 - BETA1),
                v.mul_scalar(BETA2) + g.square().mul_scalar(1.0 - BETA2),
            ),
            None => (
                g.clone().mul_scalar(1.0 - BETA1),
                g.square().mul_scalar(1.0 - BETA2),
            ),
        };
        // p ← p − lr · m̂ / (√v̂ + ε),  m̂ = m/(1−β₁ᵗ), v̂ = v/(1−β₂ᵗ)
        let update = m.clone().div_scalar(self.bias1)
            / v.clone().div_scalar(self.bias2).sqrt().add_scalar(EPS);
        let new = tensor.inner().reshape([numel]) - update.mul_scalar(self.lr);
        self.moments[i] = Some((m, v));
        Param::initialized(id, Tensor::from_inner(new.reshape(dims)).require_grad())
    }
}

impl Adam {
    /// One update of every parameter that has a gradient (`grads` in the module's visiting
    /// order, see [`super::shards::param_grads`]).
    pub fn step<M: Module>(&mut self, module: M, grads: &ParamGrads, lr: f64) -> M {
        self.step += 1;
        let t = self.step as i32;
        let mut mapper = StepMapper {
            grads,
            moments: &mut self.moments,
            index: 0,
            lr,
            bias1: 1.0 - BETA1.powi(t),
            bias2: 1.0 - BETA2.powi(t),
        };
        module.map(&mut mapper)
    }

    pub fn state(&self) -> AdamState {
        let host = |t: &Tensor<1>| t.to_data().iter::<f64>().collect::<Vec<f64>>();
        AdamState {
            step: self.step,
            moments: self
                .moments
                .iter()
                .map(|mv| mv.as_ref().map(|(m, v)| (host(m), host(v))))
                .collect(),
        }
    }

    /// Restores the state on `device` (the non-autodiff device the moments live on).
    pub fn from_state(state: &AdamState, device: &Device) -> Self {
        let dev = |v: &Vec<f64>| Tensor::from_data(TensorData::new(v.clone(), [v.len()]), device);
        Self {
            step: state.step,
            moments: state
                .moments
                .iter()
                .map(|mv| mv.as_ref().map(|(m, v)| (dev(m), dev(v))))
                .collect(),
        }
    }
}

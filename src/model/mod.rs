//! The structured Lagrangian model (docs/dynamics.md) on Burn: parameters, the dynamics
//! q̈ = M⁻¹(F − c − ∂V/∂q), one-step prediction by an integrator, and the loss.

mod fused;
mod init;
mod loss;
mod multibody;
pub mod network;
pub mod params;
pub mod params_io;

// The model as its file describes it lives in the inference core (ARCHITECTURE.md).
pub use graybox_core::model::{ModelConfig, NamedArray, file, names, report, spec};

use std::sync::Arc;

use burn::module::Module;
use burn::tensor::{Device, Tensor};

use crate::error::Result;
use crate::physics::params::Part;
use crate::physics::templates::Template;
use crate::rng::Rng;
use file::ModelFile;
use fused::FusedStep;
use loss::Loss;
use network::{Network, param};
use params::Components;
pub use params::Params;
use spec::ModelSpec;

/// A model bound to a device: config, parameters, the loss's constants and its step.
#[derive(Debug, Clone)]
pub struct Model {
    pub config: ModelConfig,
    pub params: Params,
    loss: Loss,
    step: Arc<FusedStep>,
    /// The same step on rows that carry their own Δt (`step_scaled`).
    timed: Arc<FusedStep>,
    /// The torque loss's errors (`torque_errors`).
    torque: Arc<FusedStep>,
}

impl Model {
    /// A freshly initialized model. `physical` gives the template's initial parameter values
    /// (defaults when `None`); networks are drawn from `seed`.
    pub fn init(
        config: ModelConfig,
        physical: Option<Vec<f64>>,
        seed: u64,
        device: &Device,
    ) -> Result<Self> {
        // M is nv × nv and F nv wide; the networks read q's features (`q_in`).
        let (n, m) = (config.nv(), config.m);
        let mut rng = Rng::derive(seed, 0x1_417);
        let widths = init::Widths {
            n,
            m,
            q_in: config.q_inputs(),
        };
        let params = match &config.spec {
            ModelSpec::Naive { hidden } => Params::Naive(Network::init(
                config.full_inputs(),
                hidden,
                n,
                &mut rng,
                device,
            )),
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                template,
            } => {
                // One rng, drawn in this order (M, V, F): a seed gives the same networks.
                let mass = init::mass(mass, &widths, &mut rng, device);
                let potential = init::potential(potential, &widths, &mut rng, device);
                let forces = init::forces(forces, &widths, &mut rng, device);
                // Physical parameters exist only when some part is white-box.
                let physical = match template
                    .as_ref()
                    .filter(|_| !config.spec.white_box_parts().is_empty())
                {
                    Some(t) => {
                        let values = physical.unwrap_or_else(|| t.defaults());
                        let raw = raw_physical(t, &values)?;
                        Some(param(raw, [1, values.len()], device))
                    }
                    None => None,
                };
                Params::Structured(Components {
                    mass,
                    potential,
                    forces,
                    physical,
                    physical_as_is: false,
                })
            }
        };
        Ok(Self::from_parts(config, params, device))
    }

    /// The model a file describes, on `device`.
    pub fn from_file(file: &ModelFile, device: &Device) -> Result<Self> {
        let skeleton = Model::init(file.config.clone(), None, 0, device)?;
        let mut params = params_io::import(skeleton.params, &file.params, device)?;
        if let Params::Structured(c) = &mut params {
            c.physical_as_is = file.params.iter().any(|a| a.name == names::PHYSICAL_VALUES);
        }
        Ok(Model::from_parts(file.config.clone(), params, device))
    }

    /// The model of `config` with `params`; a robot's q̈ comes from the multibody
    /// algorithms (see [`Model::assembled`]).
    pub fn from_parts(config: ModelConfig, params: Params, device: &Device) -> Self {
        let [step, timed, torque] = fused::ops(&config, &params, true);
        Self {
            loss: Loss::new(&config, device),
            config,
            params,
            step,
            timed,
            torque,
        }
    }

    /// This model with other values for its parameters (same config and constants).
    pub fn with_params(&self, params: Params) -> Self {
        Self {
            params,
            ..self.clone()
        }
    }

    pub fn device(&self) -> Device {
        self.loss.device()
    }

    /// The same model without autodiff tracking, for evaluation.
    pub fn valid(&self) -> Self {
        let device = self.device().without_autodiff();
        Self {
            params: self.params.valid(),
            loss: Loss::new(&self.config, &device),
            ..self.clone()
        }
    }

    /// The physical parameters as the optimiser moves them (host f64): logarithms of the
    /// positive ones, a URDF body's log-Cholesky factor (`Template::physical_from_raw`).
    pub fn raw_physical(&self) -> Option<Vec<f64>> {
        let p = self.params.components()?.physical.as_ref()?;
        Some(p.val().into_data().iter::<f64>().collect())
    }

    /// Learned physical values by name (host f64), for reports.
    pub fn physical_values(&self) -> Option<Vec<(String, f64)>> {
        let (t, raw) = (self.config.template()?, self.raw_physical()?);
        let as_is = self.params.components()?.physical_as_is;
        let values = if as_is {
            raw
        } else {
            t.physical_from_raw(&raw)
        };
        let names = t.params().iter().map(|info| info.name.to_string());
        Some(names.zip(values).collect())
    }

    /// One step of the model's integrator: x = [q, q̇] `[batch, 2n]`, u `[batch, m]`.
    pub fn step(&self, x: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
        self.fused_step(x, u, None)
    }

    /// One step of each row's own length: `scale` `[batch, 1]` is Δt_i / Δt (a dataset's
    /// `steps` over its `dt`).
    pub fn step_scaled(&self, x: Tensor<2>, u: Tensor<2>, scale: Tensor<2>) -> Tensor<2> {
        self.fused_step(x, u, Some(scale))
    }

    /// Sum over the batch of Σ(q' − q̂')² + λ Σ(q̇' − q̂̇')² (divide by the batch size for the
    /// mean); an angle's position term is 2(1 − cos(q' − q̂')).
    pub fn loss_sum(&self, x: Tensor<2>, u: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
        self.error_sum(self.step(x, u), target)
    }

    /// The same sum for predicted states against targets (a rollout's step).
    pub fn error_sum(&self, predicted: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
        self.loss.sum(predicted - target)
    }

    /// The white-box parts, for reports.
    pub fn white_box_parts(&self) -> Vec<Part> {
        self.config.spec.white_box_parts()
    }
}

/// Physical values → raw trainable values (`Template::raw`).
pub fn raw_physical(t: &Template, values: &[f64]) -> Result<Vec<f64>> {
    t.raw_from_physical(values)
}

//! The structured Lagrangian model (docs/dynamics.md) on Burn: parameters, the dynamics
//! q̈ = M⁻¹(F − c − ∂V/∂q), one-step prediction by an integrator, and the loss.

mod fused;
mod init;
pub mod mlp;
mod multibody;
pub mod params;
pub mod params_io;
mod tensors;

// The model as its file describes it lives in the inference core (ARCHITECTURE.md).
pub use graybox_core::model::{ModelConfig, NamedArray, file, names, report, spec};

use burn::module::Module;
use burn::tensor::{Device, Tensor};

use crate::error::Result;
use crate::physics::assembly::{Structure, Values};
use crate::physics::dual::Dual;
use crate::physics::dynamics::{Tri, acceleration};
use crate::physics::params::Part;
use crate::physics::parts::PotentialSpec;
use crate::physics::templates::Template;
use crate::rng::Rng;
use file::ModelFile;
use mlp::{Mlp, param};
pub use params::Params;
use params::{Components, PotentialParams, Values as Trainable};
use spec::ModelSpec;
use tensors::{BurnNets, Consts, LazyColumns};
pub use tensors::{columns, dual_columns};

/// A model bound to a device: config, parameters and the derived constants.
#[derive(Debug, Clone)]
pub struct Model {
    pub config: ModelConfig,
    pub params: Params,
    consts: Consts,
}

/// The terms of M q̈ = F − c − ∂V/∂q for a batch, as `[batch, 1]` columns.
pub struct Parts {
    /// L(q) with ∂L/∂q_k.
    pub l: Tri<Dual<Tensor<2>>>,
    /// ∂V/∂q (`None` for a zero potential).
    pub grad_v: Option<Vec<Tensor<2>>>,
    pub forces: Vec<Tensor<2>>,
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
        let (n, m) = (config.n, config.m);
        let mut rng = Rng::derive(seed, 0x1_417);
        let widths = init::Widths {
            n,
            m,
            q_in: config.q_inputs(),
        };
        let params = match &config.spec {
            ModelSpec::Naive { hidden } => {
                Params::Naive(Mlp::init(config.full_inputs(), hidden, n, &mut rng, device))
            }
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

    /// The model of `config` with `params`, training through the fused step.
    pub fn from_parts(config: ModelConfig, params: Params, device: &Device) -> Self {
        let consts = Consts::new(&config, device);
        let model = Self {
            config,
            params,
            consts,
        };
        model.fused()
    }

    /// This model with other values for its parameters (same config and constants).
    pub fn with_params(&self, params: Params) -> Self {
        Self {
            config: self.config.clone(),
            params,
            consts: self.consts.clone(),
        }
    }

    pub fn device(&self) -> Device {
        self.consts.one.device()
    }

    /// The same model without autodiff tracking, for evaluation.
    pub fn valid(&self) -> Self {
        let params = self.params.valid();
        let device = self.device().without_autodiff();
        Self::from_parts(self.config.clone(), params, &device).on_path(self.is_fused())
    }

    /// Physical parameter values as tensors `[1, 1]` (positive ones exponentiated).
    /// Parameters no white-box part of this model reads are detached: a tracked value that
    /// never reaches the loss keeps its autodiff graph alive in Burn's registry, and every
    /// later backward pass slows down.
    fn physical(&self, t: &Template) -> Vec<Tensor<2>> {
        let raw = self
            .components()
            .physical
            .as_ref()
            .expect("a template model has physical parameters")
            .val();
        let parts = self.white_box_parts();
        let raw: Vec<Tensor<2>> = t
            .params()
            .iter()
            .enumerate()
            .map(|(i, info)| {
                let v = raw.clone().narrow(1, i, 1);
                if info.used_by.iter().any(|p| parts.contains(p)) {
                    v
                } else {
                    v.detach()
                }
            })
            .collect();
        if self.components().physical_as_is {
            return raw;
        }
        t.physical_from_raw(&raw)
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

    /// q̈ for a batch: q, q̇ `[batch, n]`, u `[batch, m]` → `[batch, n]`.
    pub fn accel(&self, q: Tensor<2>, qd: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
        if let Params::Naive(net) = &self.params {
            let c = &self.consts;
            let input = c.full_input(&q, &qd, &u);
            return net.forward(input) * c.acc_std.clone() + c.acc_mean.clone();
        }
        if let Some(fd) = &self.consts.multibody {
            return self.multibody_accel(fd, q, qd, u);
        }
        let qd_cols = columns(&qd);
        let p = self.parts(q, qd, u);
        Tensor::cat(acceleration(&p.l, p.grad_v, p.forces, &qd_cols), 1)
    }

    /// The terms of the manipulator equation of a structured model, as `[batch, 1]` columns:
    /// the networks run here on whole tensors, the structure is the one assembly
    /// ([`assembly`]) inference runs too.
    pub fn parts(&self, q: Tensor<2>, qd: Tensor<2>, u: Tensor<2>) -> Parts {
        self.assemble(q, qd, u, |structure, nets, inputs| {
            let t = structure.terms(nets, inputs);
            Parts {
                l: t.l,
                grad_v: t.grad_v,
                forces: t.forces,
            }
        })
    }

    /// `f` of a structured model's assembly on a batch: its structure with the values it
    /// reads, its networks' outputs, and the batch's columns.
    fn assemble<R>(
        &self,
        q: Tensor<2>,
        qd: Tensor<2>,
        u: Tensor<2>,
        f: impl FnOnce(&Structure<'_, Tensor<2>>, &BurnNets, &LazyColumns<'_>) -> R,
    ) -> R {
        let c = &self.consts;
        let ModelSpec::Structured {
            mass,
            potential,
            forces,
            template,
        } = &self.config.spec
        else {
            panic!("parts() is for structured models");
        };
        let p = self.components();
        let nets = self.networks(&q, &qd, &u);
        let value_columns = |t: Option<&Trainable>| t.map(|t| columns(&t.val()));
        let (mass_const, potential_quad, b_const, eta) = (
            value_columns(p.mass_const()),
            value_columns(p.potential_quad()),
            value_columns(p.b_const()),
            value_columns(p.eta()),
        );
        let physical = template
            .as_ref()
            .filter(|_| p.physical.is_some())
            .map(|t| self.physical(t));
        let structure = Structure {
            mass,
            potential,
            forces,
            template: template.as_ref(),
            scaling: &self.config.scaling,
            values: Values {
                mass_const: mass_const.as_deref(),
                potential_quad: potential_quad.as_deref(),
                b_const: b_const.as_deref(),
                eta: eta.as_deref(),
                physical: physical.as_deref(),
            },
            n: self.config.n,
            m: self.config.m,
        };
        let inputs = LazyColumns::new(&q, &qd, &u, &c.one);
        f(&structure, &nets, &inputs)
    }

    /// The structured model's networks on a batch, as columns.
    fn networks(&self, q: &Tensor<2>, qd: &Tensor<2>, u: &Tensor<2>) -> BurnNets {
        tensors::networks(&self.consts, self.components(), self.config.n, [q, qd, u])
    }

    fn components(&self) -> &Components {
        self.params
            .components()
            .expect("a structured model's parameters are per component")
    }

    /// V(q) `[batch, 1]` for a structured model (`None` for a zero potential or the naive
    /// model). Training only needs ∂V/∂q; this is for energy diagnostics and checks.
    pub fn potential(&self, q: Tensor<2>) -> Option<Tensor<2>> {
        let c = &self.consts;
        let ModelSpec::Structured {
            potential,
            template,
            ..
        } = &self.config.spec
        else {
            return None;
        };
        let s = &self.config.scaling;
        let network = |q: Tensor<2>| {
            let Some(PotentialParams::Net(net)) = &self.components().potential else {
                unreachable!("a network potential has a network");
            };
            net.forward(c.q_input(&q, false).0)
                .mul_scalar(s.potential_scale())
        };
        match potential {
            PotentialSpec::Zero => None,
            PotentialSpec::Mlp { .. } => Some(network(q)),
            PotentialSpec::Quadratic => {
                // ½ qᵀKq = Σ_i ½ K_ii q_i² + Σ_{i>j} K_ij q_i q_j
                let Some(PotentialParams::Quadratic(k)) = &self.components().potential else {
                    unreachable!("a quadratic potential has its K");
                };
                let k = k.val();
                let cols = columns(&q);
                let n = cols.len();
                let terms = (0..n)
                    .flat_map(|i| (0..=i).map(move |j| (i, j)))
                    .map(|(i, j)| {
                        let kij = k.clone().narrow(1, Tri::<()>::index(i, j), 1);
                        let w = if i == j { 0.5 } else { 1.0 };
                        (cols[i].clone() * cols[j].clone() * kij).mul_scalar(w)
                    });
                let v = terms.reduce(|a, b| a + b).expect("n ≥ 1");
                Some(v.mul_scalar(s.quadratic_scale()))
            }
            PotentialSpec::Template { residual } => {
                let t = template.as_ref().expect("validated: template present");
                let v = t.potential(&self.physical(t), &columns(&q));
                Some(match residual {
                    None => v,
                    Some(_) => v + network(q),
                })
            }
        }
    }

    /// One step of the model's integrator: x = [q, q̇] `[batch, 2n]`, u `[batch, m]`.
    pub fn step(&self, x: Tensor<2>, u: Tensor<2>) -> Tensor<2> {
        if let Some(f) = &self.consts.fused {
            return self.fused_step(f, x, u);
        }
        let n = self.config.n;
        self.config
            .integrator
            .step(&x, self.config.dt, |x: &Tensor<2>| {
                let q = x.clone().narrow(1, 0, n);
                let qd = x.clone().narrow(1, n, n);
                let qdd = self.accel(q, qd.clone(), u.clone());
                Tensor::cat(vec![qd, qdd], 1)
            })
    }

    /// Sum over the batch of Σ(q' − q̂')² + λ Σ(q̇' − q̂̇')² (divide by the batch size for the
    /// mean); an angle's position term is 2(1 − cos(q' − q̂')).
    pub fn loss_sum(&self, x: Tensor<2>, u: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
        self.error_sum(self.step(x, u), target)
    }

    /// The same sum for predicted states against targets (a rollout's step).
    pub fn error_sum(&self, predicted: Tensor<2>, target: Tensor<2>) -> Tensor<1> {
        let err = predicted - target;
        (self.consts.squared_error(err) * self.consts.loss_w.clone()).sum()
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

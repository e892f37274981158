//! The f64 inference path for trained models, outside Burn's per-op graph: the same math as
//! training (MLPs with forward-mode input derivatives, the Coriolis term, the Cholesky solve,
//! the integrator) over plain arrays, written generically over [`Scalar`] so that dual numbers
//! give exact derivatives of the one-step map (Linearize) with no finite differences.
//!
//! Weights come from the model file (Burn's layout: Linear weights `[in, out]`).

use std::collections::HashMap;

use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::model::dual::Dual;
use crate::model::dynamics::{Tri, acceleration};
use crate::model::mass_matrix::factor_from_outputs;
use crate::model::params_io::NamedArray;
use crate::model::scalar::Scalar;
use crate::model::spec::{ForceSpec, MassSpec, ModelSpec, PotentialSpec};
use crate::model::templates::Template;
use crate::train::artifact::ModelFile;

/// An MLP's weights: per layer, W row-major `[in, out]` and b `[out]`.
#[derive(Debug, Clone)]
pub struct Mlp64 {
    layers: Vec<(usize, usize, Vec<f64>, Vec<f64>)>,
}

impl Mlp64 {
    fn from_arrays(arrays: &HashMap<&str, &NamedArray>, prefix: &str) -> Result<Option<Self>> {
        let mut layers = vec![];
        for i in 0.. {
            let (Some(w), Some(b)) = (
                arrays.get(format!("{prefix}.layers.{i}.weight").as_str()),
                arrays.get(format!("{prefix}.layers.{i}.bias").as_str()),
            ) else {
                break;
            };
            let (d_in, d_out) = (w.shape[0], w.shape[1]);
            if b.values.len() != d_out || w.values.len() != d_in * d_out {
                return Err(Error::corrupt(
                    "model file",
                    format!("{prefix} layer {i} has inconsistent shapes"),
                ));
            }
            layers.push((d_in, d_out, w.values.clone(), b.values.clone()));
        }
        Ok((!layers.is_empty()).then_some(Self { layers }))
    }

    /// y = W_L tanh(… tanh(W_1 x + b_1) …) + b_L over any scalar (dual numbers carry input
    /// derivatives through, as the Burn path's Jacobian recursion does).
    pub fn forward<S: Scalar>(&self, x: &[S]) -> Vec<S> {
        let last = self.layers.len() - 1;
        let mut h: Vec<S> = x.to_vec();
        for (l, (d_in, d_out, w, b)) in self.layers.iter().enumerate() {
            debug_assert_eq!(h.len(), *d_in);
            let z: Vec<S> = (0..*d_out)
                .map(|j| {
                    let s = (0..*d_in)
                        .map(|i| h[i].scale(w[i * d_out + j]))
                        .reduce(|a, b| a + b)
                        .expect("a layer has inputs");
                    s.shift(b[j])
                })
                .collect();
            h = if l == last {
                z
            } else {
                z.iter().map(Scalar::tanh).collect()
            };
        }
        h
    }
}

/// A trained model ready for f64 inference.
#[derive(Debug, Clone)]
pub struct Evaluator {
    pub config: ModelConfig,
    mass_net: Option<Mlp64>,
    mass_const: Option<Vec<f64>>,
    potential_net: Option<Mlp64>,
    potential_quad: Option<Vec<f64>>,
    force_net: Option<Mlp64>,
    b_net: Option<Mlp64>,
    b_const: Option<Vec<f64>>,
    eta: Option<Vec<f64>>,
    /// Physical values (positive ones already exponentiated).
    physical: Option<Vec<f64>>,
    naive: Option<Mlp64>,
}

impl Evaluator {
    pub fn from_file(file: &ModelFile) -> Result<Self> {
        let arrays: HashMap<&str, &NamedArray> =
            file.params.iter().map(|a| (a.name.as_str(), a)).collect();
        let flat = |name: &str| arrays.get(name).map(|a| a.values.clone());
        let physical = match (file.config.template(), flat("physical")) {
            (Some(t), Some(raw)) => Some(
                t.params()
                    .iter()
                    .zip(raw)
                    .map(|(info, r)| if info.positive { r.exp() } else { r })
                    .collect(),
            ),
            _ => None,
        };
        Ok(Self {
            config: file.config.clone(),
            mass_net: Mlp64::from_arrays(&arrays, "mass_net")?,
            mass_const: flat("mass_const"),
            potential_net: Mlp64::from_arrays(&arrays, "potential_net")?,
            potential_quad: flat("potential_quad"),
            force_net: Mlp64::from_arrays(&arrays, "force_net")?,
            b_net: Mlp64::from_arrays(&arrays, "b_net")?,
            b_const: flat("b_const"),
            eta: flat("eta"),
            physical,
            naive: Mlp64::from_arrays(&arrays, "naive")?,
        })
    }

    fn template(&self) -> Template {
        self.config
            .template()
            .expect("validated: white-box parts have a template")
    }

    fn phys<S: Scalar>(&self, like: &S) -> Vec<S> {
        self.physical
            .as_ref()
            .expect("a template model has physical parameters")
            .iter()
            .map(|&v| like.lift(v))
            .collect()
    }

    /// q̈ for one sample.
    pub fn accel<S: Scalar>(&self, q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        let s = &self.config.scaling;
        let standardize = |x: &[S], mean: &[f64], std: &[f64]| -> Vec<S> {
            x.iter()
                .zip(mean.iter().zip(std))
                .map(|(x, (m, sd))| x.shift(-m).scale(1.0 / sd))
                .collect()
        };
        let full_input = || -> Vec<S> {
            let mut v = standardize(q, &s.q_mean, &s.q_std);
            v.extend(standardize(qd, &s.qdot_mean, &s.qdot_std));
            v.extend(standardize(u, &s.u_mean, &s.u_std));
            v
        };
        let ModelSpec::Structured {
            mass,
            potential,
            forces,
            ..
        } = &self.config.spec
        else {
            let out = self
                .naive
                .as_ref()
                .expect("naive net")
                .forward(&full_input());
            return out
                .iter()
                .zip(s.acc_std.iter().zip(&s.acc_mean))
                .map(|(y, (sd, m))| y.scale(*sd).shift(*m))
                .collect();
        };
        let n = q.len();
        // q as dual variables for the parts that need ∂/∂q (M and V).
        let qv: Vec<Dual<S>> = q
            .iter()
            .enumerate()
            .map(|(k, x)| Dual::variable(x.clone(), k, n, x.lift(1.0)))
            .collect();
        let l: Tri<Dual<S>> = match mass {
            MassSpec::Mlp { .. } => {
                let x = standardize_dual(&qv, &s.q_mean, &s.q_std);
                factor_from_outputs(self.mass_net.as_ref().expect("mass net").forward(&x), n)
            }
            MassSpec::Constant => {
                let raw = self.mass_const.as_ref().expect("constant mass");
                factor_from_outputs(
                    raw.iter().map(|&v| Dual::constant(q[0].lift(v))).collect(),
                    n,
                )
            }
            MassSpec::Template => {
                let p: Vec<Dual<S>> = self.phys(&q[0]).into_iter().map(Dual::constant).collect();
                crate::model::dynamics::cholesky(&self.template().mass(&p, &qv))
            }
        };
        let tangent =
            |v: &Dual<S>, k: usize| v.tangent(k).cloned().unwrap_or_else(|| q[0].lift(0.0));
        let grad_v: Option<Vec<S>> = match potential {
            PotentialSpec::Zero => None,
            PotentialSpec::Mlp { .. } => {
                let x = standardize_dual(&qv, &s.q_mean, &s.q_std);
                let v = &self
                    .potential_net
                    .as_ref()
                    .expect("potential net")
                    .forward(&x)[0];
                Some(
                    (0..n)
                        .map(|k| tangent(v, k).scale(s.potential_scale()))
                        .collect(),
                )
            }
            PotentialSpec::Quadratic => {
                let k = self.potential_quad.as_ref().expect("quadratic potential");
                let kij = |i: usize, j: usize| {
                    if j <= i {
                        k[Tri::<()>::index(i, j)]
                    } else {
                        k[Tri::<()>::index(j, i)]
                    }
                };
                Some(
                    (0..n)
                        .map(|i| {
                            (0..n)
                                .map(|j| q[j].scale(kij(i, j)))
                                .reduce(|a, b| a + b)
                                .expect("n ≥ 1")
                                .scale(s.quadratic_scale())
                        })
                        .collect(),
                )
            }
            PotentialSpec::Template => {
                let p: Vec<Dual<S>> = self.phys(&q[0]).into_iter().map(Dual::constant).collect();
                let v = self.template().potential(&p, &qv);
                Some((0..n).map(|k| tangent(&v, k)).collect())
            }
        };
        let m = u.len();
        let affine = |b: Vec<S>, eta: &[f64]| -> Vec<S> {
            (0..n)
                .map(|i| {
                    let bu = (0..m)
                        .map(|j| b[i * m + j].clone() * u[j].clone())
                        .reduce(|a, b| a + b)
                        .expect("m ≥ 1");
                    bu + qd[i].scale(eta[i] * s.force_scale[i] / s.qdot_std[i])
                })
                .collect()
        };
        let b_scale = |i: usize, j: usize| s.force_scale[i] / s.u_std[j];
        let f: Vec<S> = match forces {
            ForceSpec::Mlp { .. } => {
                let out = self
                    .force_net
                    .as_ref()
                    .expect("force net")
                    .forward(&full_input());
                out.iter()
                    .zip(&s.force_scale)
                    .map(|(y, fs)| y.scale(*fs))
                    .collect()
            }
            ForceSpec::ControlAffine { .. } => {
                let x = standardize(q, &s.q_mean, &s.q_std);
                let raw = self.b_net.as_ref().expect("B net").forward(&x);
                let b = raw
                    .iter()
                    .enumerate()
                    .map(|(k, v)| v.scale(b_scale(k / m, k % m)))
                    .collect();
                affine(b, self.eta.as_ref().expect("eta"))
            }
            ForceSpec::ConstantAffine => {
                let raw = self.b_const.as_ref().expect("constant B");
                let b = raw
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| q[0].lift(v * b_scale(k / m, k % m)))
                    .collect();
                affine(b, self.eta.as_ref().expect("eta"))
            }
            ForceSpec::Template => self.template().forces(&self.phys(&q[0]), q, qd, u),
        };
        acceleration(&l, grad_v, f, qd)
    }

    /// One step of the model's integrator: x = [q, q̇] → x'.
    pub fn step<S: Scalar>(&self, x: &[S], u: &[S]) -> Vec<S> {
        let n = self.config.n;
        self.config
            .integrator
            .step(&x.to_vec(), self.config.dt, |x: &Vec<S>| {
                let (q, qd) = x.split_at(n);
                let qdd = self.accel(q, qd, u);
                qd.iter().cloned().chain(qdd).collect()
            })
    }

    /// The one-step map's Jacobians A = ∂x'/∂x (2n×2n) and B = ∂x'/∂u (2n×m), row-major,
    /// exact through dual numbers (second derivatives of M and V included).
    pub fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (nx, m) = (x.len(), u.len());
        let dirs = nx + m;
        let var = |v: f64, k: usize| Dual::variable(v, k, dirs, 1.0);
        let xd: Vec<Dual<f64>> = x.iter().enumerate().map(|(k, &v)| var(v, k)).collect();
        let ud: Vec<Dual<f64>> = u.iter().enumerate().map(|(k, &v)| var(v, nx + k)).collect();
        let next = self.step(&xd, &ud);
        let d = |y: &Dual<f64>, k: usize| y.tangent(k).copied().unwrap_or(0.0);
        let a = next
            .iter()
            .flat_map(|y| (0..nx).map(move |k| d(y, k)))
            .collect();
        let b = next
            .iter()
            .flat_map(|y| (nx..dirs).map(move |k| d(y, k)))
            .collect();
        (a, b)
    }
}

fn standardize_dual<S: Scalar>(x: &[Dual<S>], mean: &[f64], std: &[f64]) -> Vec<Dual<S>> {
    x.iter()
        .zip(mean.iter().zip(std))
        .map(|(x, (m, sd))| x.shift(-m).scale(1.0 / sd))
        .collect()
}

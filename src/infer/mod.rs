//! The f64 inference path for trained models, outside Burn's per-op graph: the same math as
//! training (MLPs with forward-mode input derivatives, the Coriolis term, the Cholesky solve,
//! the integrator) over plain arrays, written generically over [`Scalar`] so that dual numbers
//! give exact derivatives of the one-step map (Linearize) with no finite differences.
//!
//! Weights come from the model file (Burn's layout: Linear weights `[in, out]`).

pub mod jet;

use std::collections::HashMap;

use jet::Jet;

use crate::control::linalg::Mat;
use crate::control::tvlqr::{Gains, tvlqr};
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

    /// The network on a batch with derivatives (see [`jet`]): one matrix product per layer.
    pub fn jet(&self, mut x: Jet) -> Jet {
        let last = self.layers.len() - 1;
        for (l, (_, d_out, w, b)) in self.layers.iter().enumerate() {
            x = x.linear(w, b, *d_out);
            if l != last {
                x.tanh();
            }
        }
        x
    }
}

/// The scalars the evaluator runs on: f64 (Predict, Rollout) or f64 dual numbers whose
/// tangents are the directions a linearization differentiates in.
pub trait Lane: Scalar {
    fn dirs(&self) -> usize;
    fn value(&self) -> f64;
    fn tangent_at(&self, j: usize) -> f64;
    fn from_parts(v: f64, tangents: &[f64]) -> Self;
}

impl Lane for f64 {
    fn dirs(&self) -> usize {
        0
    }
    fn value(&self) -> f64 {
        *self
    }
    fn tangent_at(&self, _: usize) -> f64 {
        0.0
    }
    fn from_parts(v: f64, _: &[f64]) -> Self {
        v
    }
}

impl Lane for Dual<f64> {
    fn dirs(&self) -> usize {
        self.d.len()
    }
    fn value(&self) -> f64 {
        self.v
    }
    fn tangent_at(&self, j: usize) -> f64 {
        self.tangent(j).copied().unwrap_or(0.0)
    }
    fn from_parts(v: f64, tangents: &[f64]) -> Self {
        Dual::new(v, tangents.iter().map(|&t| Some(t)))
    }
}

/// A batch's network inputs as a jet: values and outer tangents from the lanes; with
/// `inner_scale`, input k also gets the inner tangent ∂x_k/∂q_k = inner_scale[k].
fn input_jet<S: Lane>(rows: &[Vec<S>], inner_scale: Option<&[f64]>, outer: usize) -> Jet {
    let width = rows[0].len();
    let inner = inner_scale.map_or(0, <[f64]>::len);
    let mut jet = Jet::zeros(rows.len(), width, inner, outer);
    for (b, row) in rows.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            jet.set(0, 0, b, j, x.value());
            for o in 1..=outer {
                jet.set(o, 0, b, j, x.tangent_at(o - 1));
            }
        }
        for (k, &s) in inner_scale.unwrap_or(&[]).iter().enumerate() {
            jet.set(0, k + 1, b, k, s);
        }
    }
    jet
}

/// Output j of sample b as a lane (values and outer tangents).
fn lane_at<S: Lane>(jet: &Jet, i: usize, b: usize, j: usize) -> S {
    let t: Vec<f64> = (1..=jet.outer).map(|o| jet.at(o, i, b, j)).collect();
    S::from_parts(jet.at(0, i, b, j), &t)
}

/// Output j of sample b as a dual number over q (inner tangents), each part a lane.
fn dual_at<S: Lane>(jet: &Jet, b: usize, j: usize) -> Dual<S> {
    Dual::new(
        lane_at(jet, 0, b, j),
        (1..=jet.inner).map(|i| Some(lane_at(jet, i, b, j))),
    )
}

/// A structured spec's three parts.
type Parts<'a> = (&'a MassSpec, &'a PotentialSpec, &'a ForceSpec);

/// Network outputs of one batch, computed before the per-sample structure.
struct NetOutputs {
    mass: Option<Jet>,
    potential: Option<Jet>,
    force: Option<Jet>,
}

/// Batches at least this large run on two threads (a thread costs ~20 µs; a 64-state step
/// ~1 ms).
const PARALLEL_ROWS: usize = 64;

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

    /// q̈ for a batch: q `[B, n]`, q̇ `[B, n]`, u `[B, m]`, flat. The networks run once over the
    /// whole batch (matrix products); the structure (Cholesky factor, Coriolis term, solve)
    /// then runs per sample on the networks' outputs.
    pub fn accel_batch<S: Lane>(&self, q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        let (n, m) = (self.config.n, self.config.m);
        let batch = q.len() / n;
        let sc = &self.config.scaling;
        let outer = q
            .iter()
            .chain(qd)
            .chain(u)
            .map(Lane::dirs)
            .max()
            .unwrap_or(0);
        let q_rows = || -> Vec<Vec<S>> {
            q.chunks(n)
                .map(|q| standardize(q, &sc.q_mean, &sc.q_std))
                .collect()
        };
        let full_rows = || -> Vec<Vec<S>> {
            (0..batch)
                .map(|b| {
                    let mut v = standardize(&q[b * n..(b + 1) * n], &sc.q_mean, &sc.q_std);
                    v.extend(standardize(
                        &qd[b * n..(b + 1) * n],
                        &sc.qdot_mean,
                        &sc.qdot_std,
                    ));
                    v.extend(standardize(&u[b * m..(b + 1) * m], &sc.u_mean, &sc.u_std));
                    v
                })
                .collect()
        };
        let ModelSpec::Structured {
            mass,
            potential,
            forces,
            ..
        } = &self.config.spec
        else {
            let out = net(&self.naive).jet(input_jet(&full_rows(), None, outer));
            return (0..batch)
                .flat_map(|b| {
                    let out = &out;
                    (0..n).map(move |j| {
                        lane_at::<S>(out, 0, b, j)
                            .scale(sc.acc_std[j])
                            .shift(sc.acc_mean[j])
                    })
                })
                .collect();
        };
        let inv_std: Vec<f64> = sc.q_std.iter().map(|s| 1.0 / s).collect();
        let q_jet = |inner: bool| input_jet(&q_rows(), inner.then_some(&inv_std[..]), outer);
        let nets = NetOutputs {
            mass: matches!(mass, MassSpec::Mlp { .. })
                .then(|| net(&self.mass_net).jet(q_jet(true))),
            potential: matches!(potential, PotentialSpec::Mlp { .. })
                .then(|| net(&self.potential_net).jet(q_jet(true))),
            force: match forces {
                ForceSpec::Mlp { .. } => {
                    Some(net(&self.force_net).jet(input_jet(&full_rows(), None, outer)))
                }
                ForceSpec::ControlAffine { .. } => Some(net(&self.b_net).jet(q_jet(false))),
                _ => None,
            },
        };
        (0..batch)
            .flat_map(|b| {
                let (qb, qdb, ub) = (
                    &q[b * n..(b + 1) * n],
                    &qd[b * n..(b + 1) * n],
                    &u[b * m..(b + 1) * m],
                );
                self.structure((mass, potential, forces), &nets, b, qb, qdb, ub)
            })
            .collect()
    }

    /// q̈ of sample b from the networks' outputs: M = LLᵀ, ∇V, F, then the manipulator
    /// equation (the same generic code the Burn path trains with).
    fn structure<S: Lane>(
        &self,
        parts: Parts,
        nets: &NetOutputs,
        b: usize,
        q: &[S],
        qd: &[S],
        u: &[S],
    ) -> Vec<S> {
        let (mass, potential, forces) = parts;
        let s = &self.config.scaling;
        let (n, m) = (q.len(), u.len());
        let zero = q[0].lift(0.0);
        // q as dual variables for the template parts that need ∂/∂q.
        let qv: Vec<Dual<S>> = q
            .iter()
            .enumerate()
            .map(|(k, x)| Dual::variable(x.clone(), k, n, x.lift(1.0)))
            .collect();
        let l: Tri<Dual<S>> = match mass {
            MassSpec::Mlp { .. } => {
                let out = nets.mass.as_ref().expect("mass outputs");
                factor_from_outputs((0..out.width).map(|j| dual_at(out, b, j)).collect(), n)
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
        let tangent = |v: &Dual<S>, k: usize| v.tangent(k).cloned().unwrap_or_else(|| zero.clone());
        let grad_v: Option<Vec<S>> = match potential {
            PotentialSpec::Zero => None,
            PotentialSpec::Mlp { .. } => {
                let v = dual_at(nets.potential.as_ref().expect("potential outputs"), b, 0);
                Some(
                    (0..n)
                        .map(|k| tangent(&v, k).scale(s.potential_scale()))
                        .collect(),
                )
            }
            PotentialSpec::Quadratic => {
                let k = self.potential_quad.as_ref().expect("quadratic potential");
                let kij = |i: usize, j: usize| k[Tri::<()>::index(i.max(j), i.min(j))];
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
                let out = nets.force.as_ref().expect("force outputs");
                (0..n)
                    .map(|j| lane_at::<S>(out, 0, b, j).scale(s.force_scale[j]))
                    .collect()
            }
            ForceSpec::ControlAffine { .. } => {
                let out = nets.force.as_ref().expect("B outputs");
                let bm = (0..n * m)
                    .map(|k| lane_at::<S>(out, 0, b, k).scale(b_scale(k / m, k % m)))
                    .collect();
                affine(bm, self.eta.as_ref().expect("eta"))
            }
            ForceSpec::ConstantAffine => {
                let raw = self.b_const.as_ref().expect("constant B");
                let bm = raw
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| q[0].lift(v * b_scale(k / m, k % m)))
                    .collect();
                affine(bm, self.eta.as_ref().expect("eta"))
            }
            ForceSpec::Template => self.template().forces(&self.phys(&q[0]), q, qd, u),
        };
        acceleration(&l, grad_v, f, qd)
    }

    /// q̈ for one sample.
    pub fn accel<S: Lane>(&self, q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        self.accel_batch(q, qd, u)
    }

    /// One step of the model's integrator for a batch: x `[B, 2n]`, u `[B, m]` → x'.
    pub fn step_batch<S: Lane>(&self, x: &[S], u: &[S]) -> Vec<S> {
        let n = self.config.n;
        self.config
            .integrator
            .step(&x.to_vec(), self.config.dt, |x: &Vec<S>| {
                let (q, qd): (Vec<S>, Vec<S>) = x
                    .chunks(2 * n)
                    .flat_map(|r| (0..n).map(move |i| (r[i].clone(), r[n + i].clone())))
                    .unzip();
                let qdd = self.accel_batch(&q, &qd, u);
                qd.chunks(n)
                    .zip(qdd.chunks(n))
                    .flat_map(|(a, b)| a.iter().chain(b).cloned())
                    .collect()
            })
    }

    /// One step for one sample: x = [q, q̇] → x'.
    pub fn step<S: Lane>(&self, x: &[S], u: &[S]) -> Vec<S> {
        self.step_batch(x, u)
    }

    /// The one-step map's Jacobians A = ∂x'/∂x (2n×2n) and B = ∂x'/∂u (2n×m), row-major,
    /// exact through dual numbers (second derivatives of M and V included).
    pub fn linearize(&self, x: &[f64], u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        self.linearize_batch(x, u)
    }
}

/// A model can leave its range (states far outside the training data, huge inputs): its
/// outputs are then not finite, which a controller must hear as an error, not as numbers.
pub fn finite_rows(field: &str, what: &str, out: &[f64], width: usize) -> Result<()> {
    match out.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::invalid(
            field,
            format!(
                "the model's {what} at row {} is not finite: the input is outside what the model can evaluate",
                i / width.max(1)
            ),
        )),
    }
}

fn net(n: &Option<Mlp64>) -> &Mlp64 {
    n.as_ref().expect("the spec's network is in the model file")
}

fn standardize<S: Scalar>(x: &[S], mean: &[f64], std: &[f64]) -> Vec<S> {
    x.iter()
        .zip(mean.iter().zip(std))
        .map(|(x, (m, sd))| x.shift(-m).scale(1.0 / sd))
        .collect()
}

/// Batched entry points over row-major arrays: what the service and the benchmarks call.
impl Evaluator {
    /// x' (and q̈ when asked) for `[B, 2n]` states and `[B, m]` inputs.
    pub fn predict(&self, x: &[f64], u: &[f64], want_accel: bool) -> (Vec<f64>, Option<Vec<f64>>) {
        let n = self.config.n;
        let next = self.split(x, u, |x, u| self.step_batch(x, u));
        let acc = want_accel.then(|| {
            self.split(x, u, |x, u| {
                let (q, qd): (Vec<f64>, Vec<f64>) = x
                    .chunks(2 * n)
                    .flat_map(|r| (0..n).map(move |i| (r[i], r[n + i])))
                    .unzip();
                self.accel_batch(&q, &qd, u)
            })
        });
        (next, acc)
    }

    /// A `[B, 2n, 2n]` and B `[B, 2n, m]` for a batch: every sample's state and input are
    /// dual variables (its own 2n + m directions), pushed through one batched step.
    pub fn linearize_batch(&self, x: &[f64], u: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (nx, m) = (2 * self.config.n, self.config.m);
        let dirs = nx + m;
        let both = self.split(x, u, |x, u| {
            let var = |v: f64, k: usize| Dual::variable(v, k, dirs, 1.0);
            let xd: Vec<Dual<f64>> = x.iter().enumerate().map(|(k, &v)| var(v, k % nx)).collect();
            let ud: Vec<Dual<f64>> = u
                .iter()
                .enumerate()
                .map(|(k, &v)| var(v, nx + k % m))
                .collect();
            self.step_batch(&xd, &ud)
                .iter()
                .flat_map(|y| (0..dirs).map(|k| y.tangent_at(k)))
                .collect()
        });
        let (mut a, mut b) = (Vec::with_capacity(both.len()), Vec::new());
        for row in both.chunks(dirs) {
            a.extend(&row[..nx]);
            b.extend(&row[nx..]);
        }
        (a, b)
    }

    /// Runs `f` over a batch, in two halves on two threads when the batch is large enough
    /// for the thread to pay off; results are concatenated in order.
    fn split(
        &self,
        x: &[f64],
        u: &[f64],
        f: impl Fn(&[f64], &[f64]) -> Vec<f64> + Sync,
    ) -> Vec<f64> {
        let (nx, m) = (2 * self.config.n, self.config.m);
        let rows = x.len() / nx;
        if rows < PARALLEL_ROWS {
            return f(x, u);
        }
        let half = rows / 2;
        let (x0, x1) = x.split_at(half * nx);
        let (u0, u1) = u.split_at(half * m);
        std::thread::scope(|s| {
            let second = s.spawn(|| f(x1, u1));
            let mut out = f(x0, u0);
            out.extend(second.join().expect("inference thread"));
            out
        })
    }

    /// TVLQR gains along a nominal `x̄ [(T+1), 2n]`, `ū [T, m]` (defects ignored).
    pub fn tvlqr(&self, xbar: &[f64], ubar: &[f64], q: &Mat, r: &Mat, qf: &Mat) -> Result<Gains> {
        let (nx, m) = (2 * self.config.n, self.config.m);
        let t = ubar.len() / m;
        let (a, b) = self.linearize_batch(&xbar[..t * nx], ubar);
        finite_rows("x_bar", "linearization", &a, nx * nx)?;
        finite_rows("x_bar", "linearization", &b, nx * m)?;
        let a: Vec<Mat> = a
            .chunks(nx * nx)
            .map(|a| Mat::new(nx, nx, a.to_vec()))
            .collect();
        let b: Vec<Mat> = b
            .chunks(nx * m)
            .map(|b| Mat::new(nx, m, b.to_vec()))
            .collect();
        tvlqr(&a, &b, q, r, qf)
    }

    /// `steps` states after x0 under inputs `u_t = input(t, x_t)`, each handed to `emit`
    /// (state, input) as computed; `emit` returning false stops the rollout early.
    pub fn rollout(
        &self,
        x0: &[f64],
        steps: usize,
        input: impl Fn(usize, &[f64]) -> Vec<f64>,
        mut emit: impl FnMut(&[f64], &[f64]) -> bool,
    ) {
        let mut x = x0.to_vec();
        for t in 0..steps {
            let u = input(t, &x);
            x = self.step(&x, &u);
            if !emit(&x, &u) {
                return;
            }
        }
    }
}

//! The f64 inference path for trained models, outside Burn's per-op graph: the same math as
//! training (MLPs with forward-mode input derivatives, the Coriolis term, the Cholesky solve,
//! the integrator) over plain arrays, written generically over [`Scalar`] so that dual numbers
//! give exact derivatives of the one-step map (Linearize) with no finite differences.
//!
//! Weights come from the model file (Burn's layout: Linear weights `[in, out]`).

pub mod activations;
mod calls;
pub mod col;
mod continuous;
mod energy;
pub mod energy_report;
mod ensemble;
mod gains;
pub mod horizons;
pub mod limits;
mod multibody;
mod nets;
pub mod particles;
mod weights;

use std::sync::Arc;

use activations::Activations;
pub use energy::{Energies, NamedPart};
pub use nets::Mlp64;
use nets::{JetNets, input_jet, networks, periodic_full_jet, periodic_q_jet};
use weights::Weights;

use col::{Column, Lanes};

use crate::arena::{AVec, Arena, CollectIn};
use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::model::file::ModelFile;
use crate::model::spec::ModelSpec;
use crate::physics::assembly::{Columns, Structure, Terms};
use crate::physics::dynamics::acceleration;
use crate::physics::multibody::forward_dynamics;
use crate::physics::scalar::Scalar;

/// A trained model ready for f64 inference.
#[derive(Debug, Clone)]
pub struct Evaluator {
    pub config: ModelConfig,
    weights: Weights,
    /// A URDF model's robot for the multibody algorithms, at its physical values.
    multibody: Option<crate::physics::multibody::Model>,
    /// An ensemble's members, each a single model (member 0's weights are also this one's);
    /// None for a single model. The batched entry points answer with their mean (`ensemble`).
    members: Option<Arc<[Evaluator]>>,
    /// F without the parts the spec names damping or friction (the unforced rollouts of the
    /// energy report, `energy`).
    without_damping: bool,
}

impl Evaluator {
    pub fn from_file(file: &ModelFile) -> Result<Self> {
        let one = |file: &ModelFile| -> Result<Self> {
            let weights = Weights::from_file(file)?;
            Ok(Self {
                multibody: multibody::model_of(&file.config, &weights),
                config: file.config.clone(),
                weights,
                members: None,
                without_damping: false,
            })
        };
        let mut eval = one(file)?;
        if file.member_count() > 1 {
            let members = (0..file.member_count()).map(|k| one(&file.member(k)));
            eval.members = Some(members.collect::<Result<Vec<_>>>()?.into());
        }
        Ok(eval)
    }

    /// q̈ for a batch given as columns: q and q̇ n coordinates, u m coordinates, each a whole
    /// batch. The networks run once over the batch (matrix products), then the structure
    /// (Cholesky factor, Coriolis term, solve) once on their output columns.
    pub fn accel<C: Lanes>(&self, q: &[C], qd: &[C], u: &[C]) -> Vec<C> {
        self.evaluate(q, qd, u, false)
    }

    /// The terms of M q̈ = F − c − ∂V/∂q at one state (L with its q-derivatives, ∂V/∂q, F)
    /// from the assembly; `None` for a naive model.
    pub fn terms<'a>(
        &'a self,
        arena: &'a Arena,
        q: &[f64],
        qd: &[f64],
        u: &[f64],
    ) -> Option<Terms<'a, f64>> {
        self.with_structure_in(arena, (q, qd, u), |s, nets, x| s.terms(nets, x))
    }

    /// τ = F − ∂V′/∂q of a model on the multibody algorithms, for a batch.
    fn torques<C: Lanes>(&self, q: &[C], qd: &[C], u: &[C]) -> Vec<C> {
        self.evaluate(q, qd, u, true)
    }

    /// q̈, or (`torques`, for a model on the multibody algorithms) the τ it would take.
    fn evaluate<C: Lanes>(&self, q: &[C], qd: &[C], u: &[C], torques: bool) -> Vec<C> {
        self.evaluate_in(&Arena::new(), q, qd, u, torques).to_vec()
    }

    /// [`Evaluator::evaluate`] in an arena.
    fn evaluate_in<'a, C: Lanes>(
        &'a self,
        a: &'a Arena,
        q: &[C],
        qd: &[C],
        u: &[C],
        torques: bool,
    ) -> AVec<'a, C> {
        let structured = self.with_structure_in(a, (q, qd, u), |s, nets, x| {
            self.structure(s, nets, x, torques)
        });
        if let Some(out) = structured {
            return out;
        }
        let Weights::Naive(net) = &self.weights else {
            unreachable!("the weights follow the spec")
        };
        let sc = &self.config.scaling;
        let out = net.jet(&self.full_input((q, qd, u)));
        (0..self.config.n)
            .map(|j| {
                C::read(&out, 0, j)
                    .scale(sc.acc_std[j])
                    .shift(sc.acc_mean[j])
            })
            .collect_in(a)
    }

    /// The networks' input from (q, q̇, u): standardized, angles as (sin, cos).
    fn full_input<C: Lanes>(&self, (q, qd, u): (&[C], &[C], &[C])) -> Activations {
        let sc = &self.config.scaling;
        let outer = outer_dirs((q, qd, u));
        if !self.config.periodic.is_empty() {
            return periodic_full_jet((q, qd, u), sc, &self.config.periodic, outer);
        }
        let mut v = standardize(q, &sc.q_mean, &sc.q_std);
        v.extend(standardize(qd, &sc.qdot_mean, &sc.qdot_std));
        v.extend(standardize(u, &sc.u_mean, &sc.u_std));
        input_jet(&v, None, outer)
    }

    /// `f` on a structured model's assembly, its networks' outputs on the batch and the
    /// batch itself; `None` for a naive model.
    fn with_structure<C: Lanes, T>(
        &self,
        x: (&[C], &[C], &[C]),
        f: impl FnOnce(&Structure<f64>, &JetNets<C>, &Columns<C>) -> T,
    ) -> Option<T> {
        self.with_structure_in(&Arena::new(), x, |s, nets, x| f(s, nets, x))
    }

    /// [`Evaluator::with_structure`] with the assembly's vectors in `arena`.
    fn with_structure_in<'a, C: Lanes, T>(
        &'a self,
        arena: &'a Arena,
        (q, qd, u): (&[C], &[C], &[C]),
        f: impl FnOnce(&Structure<'a, f64>, &JetNets<C>, &Columns<C>) -> T,
    ) -> Option<T> {
        let (
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                ..
            },
            Weights::Structured(w),
        ) = (&self.config.spec, &self.weights)
        else {
            return None;
        };
        let (sc, angles) = (&self.config.scaling, &self.config.periodic);
        let outer = outer_dirs((q, qd, u));
        let inv_std: Vec<f64> = sc.q_std.iter().map(|s| 1.0 / s).collect();
        let q_jet = |inner: bool| {
            if angles.is_empty() {
                let q_std = standardize(q, &sc.q_mean, &sc.q_std);
                input_jet(&q_std, inner.then_some(&inv_std[..]), outer)
            } else {
                periodic_q_jet(q, sc, angles, inner, outer)
            }
        };
        let outputs = networks(
            w,
            q_jet,
            || self.full_input((q, qd, u)),
            || self.full_input((q, qd, &[])),
        );
        let structure = Structure {
            mass,
            potential,
            forces,
            template: self.config.template(),
            scaling: sc,
            values: w.values(),
            n: q.len(),
            m: u.len(),
            arena,
        };
        Some(f(
            &structure,
            &JetNets::new(&outputs),
            &Columns { q, qd, u },
        ))
    }

    /// q̈ from the networks' outputs: the structure assembled from the spec (the same
    /// generic code training records on its tape), then the manipulator equation, or forward
    /// dynamics by the multibody algorithms with τ from the structure (`torques`: τ only).
    /// Without its damping (`without_damping`), F loses the parts the spec names so.
    fn structure<'a, S: Lanes>(
        &self,
        structure: &Structure<'a, f64>,
        nets: &JetNets<S>,
        x: &Columns<S>,
        torques: bool,
    ) -> AVec<'a, S> {
        let damping = self.without_damping.then(|| {
            let parts = structure.force_parts(nets, x).into_iter();
            let damping = parts.filter(|p| p.dissipation).map(|p| p.values);
            damping.reduce(|mut a, b| {
                a.iter_mut().zip(b).for_each(|(a, b)| *a = a.clone() + b);
                a
            })
        });
        let less = |mut f: AVec<'a, S>| {
            let d = damping.as_ref().and_then(Option::as_ref);
            for (f, d) in f.iter_mut().zip(d.into_iter().flatten()) {
                *f = f.clone() - d.clone();
            }
            f
        };
        if let Some(model) = &self.multibody {
            let tau = less(structure.multibody_torques(nets, x));
            return if torques {
                tau
            } else {
                AVec::from_iter_in(forward_dynamics(model, x.q, x.qd, &tau), structure.arena)
            };
        }
        let t = structure.terms(nets, x);
        acceleration(&t.factor, t.grad_v.as_deref(), &less(t.forces), x.qd)
    }

    /// One step of the model's integrator: x = [q, q̇] (2n coordinates), u (m) → x'.
    pub fn step<C: Lanes>(&self, x: &[C], u: &[C]) -> Vec<C> {
        self.step_in(&Arena::new(), x, u).to_vec()
    }

    /// [`Evaluator::step`] in an arena.
    pub fn step_in<'a, C: Lanes>(&'a self, a: &'a Arena, x: &[C], u: &[C]) -> AVec<'a, C> {
        let n = self.config.n;
        let x = AVec::from_iter_in(x.iter().cloned(), a);
        (self.config.integrator).step(&x, self.config.dt, |x: &AVec<C>| {
            let (q, qd) = x.split_at(n);
            let mut dx = AVec::from_iter_in(qd.iter().cloned(), a);
            dx.extend(self.evaluate_in(a, q, qd, u, false));
            dx
        })
    }
}

/// The most outer (linearization) directions any input carries.
fn outer_dirs<C: Lanes>((q, qd, u): (&[C], &[C], &[C])) -> usize {
    q.iter()
        .chain(qd)
        .chain(u)
        .map(Lanes::dirs)
        .max()
        .unwrap_or(0)
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

/// Row-major `[B, width]` as `width` batch coordinates.
fn columns<C: Column>(rows: &[f64], width: usize) -> Vec<C> {
    (0..width).map(|j| C::gather(rows, width, j)).collect()
}

/// Batch coordinates back to row-major `[B, width]`.
fn to_rows<C: Column>(cols: &[C]) -> Vec<f64> {
    (0..cols[0].rows())
        .flat_map(|b| cols.iter().map(move |c| c.get(b)))
        .collect()
}

fn standardize<S: Scalar>(x: &[S], mean: &[f64], std: &[f64]) -> Vec<S> {
    x.iter()
        .zip(mean.iter().zip(std))
        .map(|(x, (m, sd))| x.shift(-m).scale(1.0 / sd))
        .collect()
}

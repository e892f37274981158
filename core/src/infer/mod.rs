//! The f64 inference path for trained models, outside Burn's per-op graph: the same math as
//! training (MLPs with forward-mode input derivatives, the Coriolis term, the Cholesky solve,
//! the integrator) over plain arrays, written generically over [`Scalar`] so that dual numbers
//! give exact derivatives of the one-step map (Linearize) with no finite differences.
//!
//! Weights come from the model file (Burn's layout: Linear weights `[in, out]`).

pub mod activations;
mod calls;
mod continuous;
mod energy;
pub mod energy_report;
mod ensemble;
mod gains;
pub mod horizons;
mod inverse;
mod lanes;
pub mod limits;
mod multibody;
mod nets;
mod pack;
pub mod particles;
mod weights;
mod workspace;

use std::ops::Range;
use std::sync::Arc;

use activations::Activations;
pub use energy::{Energies, NamedPart};
pub use inverse::InverseDynamics;
pub use nets::Mlp64;
use nets::{JetNets, NetOutputs, input_jet, networks, periodic_full_jet, periodic_q_jet};
use weights::Weights;
pub use workspace::{Workspace, with_workspace};

use lanes::Lanes;
use pack::{NARROW, PACK};

use crate::arena::{AVec, Arena, CollectIn};
use crate::error::{Error, Result};
use crate::model::ModelConfig;
use crate::model::file::ModelFile;
use crate::model::spec::ModelSpec;
use crate::physics::assembly::{Columns, Structure, Terms};
use crate::physics::dynamics::acceleration;
use crate::physics::integrator::States;
use crate::physics::multibody::forward_dynamics_in;
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

    /// q̈ at one state.
    pub fn accel<S: Lanes>(&self, q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        let a = Arena::new();
        let x: AVec<S> = q.iter().chain(qd).cloned().collect_in(&a);
        self.evaluate_in(&a, self.rows(&x, u), false).to_vec()
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
        let x: AVec<f64> = q.iter().chain(qd).copied().collect_in(arena);
        let x = self.rows(&x, u);
        self.with_structure_in(arena, x, |s, outs| {
            s.terms(&JetNets::new(arena, outs, 0), &x.row(0))
        })
    }

    /// `[B, nq + nv]` states and `[B, m]` inputs as the evaluator reads them.
    fn rows<'x, S>(&self, x: &'x [S], u: &'x [S]) -> Rows<'x, S> {
        let (nq, nv, m) = (self.config.nq(), self.config.nv(), self.config.m);
        Rows { x, u, nq, nv, m }
    }

    /// v̇ `[B, nv]` for a batch in an arena, or (`torques`, for a model on the multibody
    /// algorithms) the τ it would take. The networks run once over the batch (matrix
    /// products), then the structure (Cholesky factor, Coriolis term, solve) on their rows:
    /// a pack of states at a time (`Lanes::Group`), or state by state for a few states and
    /// for the multibody algorithms (their recursion in f64).
    fn evaluate_in<'a, S: Lanes>(&'a self, a: &'a Arena, x: Rows<S>, torques: bool) -> AVec<'a, S> {
        let mut out = AVec::with_capacity_in(x.len() * x.nv, a);
        let structured = self.with_structure_in(a, x, |s, outs| {
            let rows = 0..x.len();
            if self.multibody.is_some() {
                return self.structure_rows(a, s, outs, x, rows, torques, &mut out);
            }
            if !S::GROUPS {
                return self.structure_groups::<S, 1>(a, s, outs, x, rows, torques, &mut out);
            }
            // Whole packs of PACK states, then packs of NARROW. A pack pays for its lanes
            // whether or not they hold a state, and a state alone costs 4–8× its lane (the
            // white-box cartpole, the formula double pendulum): fewer than an eighth of a
            // narrow pack, state by state.
            let wide = x.len() / PACK * PACK;
            self.structure_groups::<S, PACK>(a, s, outs, x, 0..wide, torques, &mut out);
            let rest = wide..x.len();
            if rest.len() >= NARROW / 8 {
                self.structure_groups::<S, NARROW>(a, s, outs, x, rest, torques, &mut out);
            } else {
                self.structure_rows(a, s, outs, x, rest, torques, &mut out);
            }
        });
        if structured.is_some() {
            return out;
        }
        let Weights::Naive(net) = &self.weights else {
            unreachable!("the weights follow the spec")
        };
        let sc = &self.config.scaling;
        let acc = net.jet(a, &self.full_input(a, &x, true));
        for b in 0..x.len() {
            out.extend((0..x.nv).map(|j| {
                S::read(&acc, b, 0, j)
                    .scale(sc.acc_std[j])
                    .shift(sc.acc_mean[j])
            }));
        }
        out
    }

    /// The structure on the batch's `rows` state by state, appended to `out`.
    #[allow(clippy::too_many_arguments)] // evaluate_in's pieces, each of what it holds
    fn structure_rows<'a, S: Lanes>(
        &self,
        a: &'a Arena,
        s: &Structure<'a, f64>,
        outs: &NetOutputs,
        x: Rows<S>,
        rows: Range<usize>,
        torques: bool,
        out: &mut AVec<'a, S>,
    ) {
        for b in rows {
            let nets = JetNets::<S>::new(a, outs, b);
            out.extend(self.structure(s, &nets, &x.row(b), torques));
        }
    }

    /// The structure on the batch's `rows` N states at a time (a group of N when `S` makes
    /// groups; the last group's missing states repeat its last, and are dropped), appended
    /// to `out`.
    #[allow(clippy::too_many_arguments)] // evaluate_in's pieces, each of what it holds
    fn structure_groups<'a, S: Lanes, const N: usize>(
        &self,
        a: &'a Arena,
        s: &Structure<'a, f64>,
        outs: &NetOutputs,
        x: Rows<S>,
        rows: Range<usize>,
        torques: bool,
        out: &mut AVec<'a, S>,
    ) {
        let per = if S::GROUPS { N } else { 1 };
        for b0 in rows.clone().step_by(per) {
            let lanes = (rows.end - b0).min(per);
            let at = |k: usize| b0 + k.min(lanes - 1);
            let cols = |part: usize, width: usize| -> AVec<S::Group<N>> {
                (0..width)
                    .map(|j| S::group::<N>(|k| x.part(part, at(k))[j].clone()))
                    .collect_in(a)
            };
            let (q, qd, u) = (cols(0, x.nq), cols(1, x.nv), cols(2, x.m));
            let nets = JetNets::<S::Group<N>>::new(a, outs, b0);
            let y = self.structure(
                s,
                &nets,
                &Columns {
                    q: &q,
                    qd: &qd,
                    u: &u,
                },
                torques,
            );
            for k in 0..lanes {
                out.extend(y.iter().map(|g| S::lane::<N>(g, k)));
            }
        }
    }

    /// The networks' input from (q, v, u) (u only `with_u`): standardized, angles as
    /// (sin, cos) and rotations as (cos, sin).
    fn full_input<'a, S: Lanes>(&self, a: &'a Arena, x: &Rows<S>, with_u: bool) -> Activations<'a> {
        let sc = &self.config.scaling;
        let outer = x.outer_dirs();
        if !self.config.space.is_real() {
            return periodic_full_jet(a, x, with_u, sc, &self.config.space, outer);
        }
        let (n, m) = (x.nq, if with_u { x.m } else { 0 });
        let value = |b: usize, j: usize| match j {
            j if j < n => standard(&x.q(b)[j], sc.q_mean[j], sc.q_std[j]),
            j if j < 2 * n => standard(&x.qd(b)[j - n], sc.qdot_mean[j - n], sc.qdot_std[j - n]),
            j => standard(
                &x.u(b)[j - 2 * n],
                sc.u_mean[j - 2 * n],
                sc.u_std[j - 2 * n],
            ),
        };
        input_jet(a, (x.len(), 2 * n + m), value, None, outer)
    }

    /// `f` on a structured model's assembly, its networks' outputs on one state and the
    /// state itself; `None` for a naive model.
    fn with_structure<T>(
        &self,
        (q, qd, u): (&[f64], &[f64], &[f64]),
        f: impl FnOnce(&Structure<f64>, &JetNets<f64>, &Columns<f64>) -> T,
    ) -> Option<T> {
        let a = Arena::new();
        let x: AVec<f64> = q.iter().chain(qd).copied().collect_in(&a);
        let x = self.rows(&x, u);
        self.with_structure_in(&a, x, |s, outs| f(s, &JetNets::new(&a, outs, 0), &x.row(0)))
    }

    /// `f` on a structured model's assembly (its vectors in `arena`) and its networks'
    /// outputs on the batch; `None` for a naive model.
    fn with_structure_in<'a, S: Lanes, T>(
        &'a self,
        arena: &'a Arena,
        x: Rows<S>,
        f: impl FnOnce(&Structure<'a, f64>, &NetOutputs) -> T,
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
        let (sc, space) = (&self.config.scaling, &self.config.space);
        let outer = x.outer_dirs();
        let inv_std: AVec<f64> = sc.q_std.iter().map(|s| 1.0 / s).collect_in(arena);
        let q_jet = |inner: bool| {
            if space.is_real() {
                let value = |b: usize, j: usize| standard(&x.q(b)[j], sc.q_mean[j], sc.q_std[j]);
                let inner = inner.then_some(&inv_std[..]);
                input_jet(arena, (x.len(), x.nq), value, inner, outer)
            } else {
                periodic_q_jet(arena, &x, sc, space, inner, outer)
            }
        };
        let outputs = networks(
            arena,
            w,
            q_jet,
            || self.full_input(arena, &x, true),
            || self.full_input(arena, &x, false),
        );
        let structure = Structure {
            mass,
            potential,
            forces,
            template: self.config.template(),
            scaling: sc,
            values: w.values(),
            space,
            m: x.m,
            arena,
        };
        Some(f(&structure, &outputs))
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
                forward_dynamics_in(structure.arena, model, x.q, x.qd, &tau)
            };
        }
        let t = structure.terms(nets, x);
        acceleration(&t.factor, t.grad_v.as_deref(), &less(t.forces), x.qd)
    }

    /// One step of the model's integrator: x = [q, v] (nq + nv values), u (m) → x'.
    pub fn step<S: Lanes>(&self, x: &[S], u: &[S]) -> Vec<S> {
        self.step_in(&Arena::new(), x, u, self.config.dt).to_vec()
    }

    /// One step of the integrator for `[B, nq + nv]` states under `[B, m]` inputs, in an
    /// arena: each stage's v̇ for the whole batch at once (`evaluate_in`), each stage's
    /// configuration moved along its tangent by `integrate` (`physics::integrator`); a step
    /// of `dt` seconds (the model's own, or a caller's: the dynamics are continuous).
    pub fn step_in<'a, S: Lanes>(&'a self, a: &'a Arena, x: &[S], u: &[S], dt: f64) -> AVec<'a, S> {
        let (nq, nv) = (self.config.nq(), self.config.nv());
        let x = AVec::from_iter_in(x.iter().cloned(), a);
        let states = States::new(&self.config.space, x.len() / (nq + nv));
        (self.config.integrator).step(&states, &x, dt, |x: &AVec<S>| {
            let vdot = self.evaluate_in(a, self.rows(x, u), false);
            let mut dx = AVec::with_capacity_in(2 * nv * states.rows, a);
            for (x, vdot) in x.chunks(nq + nv).zip(vdot.chunks(nv)) {
                dx.extend(x[nq..].iter().cloned());
                dx.extend(vdot.iter().cloned());
            }
            dx
        })
    }
}

/// States row by row: x `[B, nq + nv]` (q then v in each row) and u `[B, m]`.
pub(super) struct Rows<'x, S> {
    pub(super) x: &'x [S],
    pub(super) u: &'x [S],
    pub(super) nq: usize,
    pub(super) nv: usize,
    pub(super) m: usize,
}

impl<S> Clone for Rows<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S> Copy for Rows<'_, S> {}

impl<'x, S: Lanes> Rows<'x, S> {
    fn len(&self) -> usize {
        self.x.len() / (self.nq + self.nv)
    }
    fn q(&self, b: usize) -> &'x [S] {
        &self.x[(self.nq + self.nv) * b..][..self.nq]
    }
    fn qd(&self, b: usize) -> &'x [S] {
        &self.x[(self.nq + self.nv) * b + self.nq..][..self.nv]
    }
    fn u(&self, b: usize) -> &'x [S] {
        &self.u[self.m * b..][..self.m]
    }
    /// State b's q (`part` 0), q̇ (1) or u (2).
    fn part(&self, part: usize, b: usize) -> &'x [S] {
        match part {
            0 => self.q(b),
            1 => self.qd(b),
            _ => self.u(b),
        }
    }
    fn row(&self, b: usize) -> Columns<'x, S> {
        Columns {
            q: self.q(b),
            qd: self.qd(b),
            u: self.u(b),
        }
    }
    /// The most outer (linearization) directions any input carries.
    fn outer_dirs(&self) -> usize {
        (self.x.iter().chain(self.u))
            .map(Lanes::dirs)
            .max()
            .unwrap_or(0)
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

fn standard<S: Scalar>(x: &S, mean: f64, std: f64) -> S {
    x.shift(-mean).scale(1.0 / std)
}

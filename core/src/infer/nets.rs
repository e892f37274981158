//! The networks on the inference path: their weights, their batched evaluation with
//! derivatives (jets), and their outputs as the model's assembly reads them.

use std::collections::HashMap;
use std::ops::Range;

use super::Rows;
use super::activations::Activations;
use super::lanes::Lanes;
use super::weights::{Components, Forces};
use crate::arena::{AVec, Arena, CollectIn};
use crate::error::{Error, Result};
use crate::model::NamedArray;
use crate::physics::assembly::Networks;
use crate::physics::dual::{Dual, groups};
use crate::physics::scaling::Scaling;
use crate::physics::space::Space;

/// An MLP's weights: per layer, W row-major `[in, out]` and b `[out]`.
#[derive(Debug, Clone)]
pub struct Mlp64 {
    pub(super) layers: Vec<(usize, usize, Vec<f64>, Vec<f64>)>,
}

impl Mlp64 {
    pub(super) fn from_arrays(
        arrays: &HashMap<&str, &NamedArray>,
        prefix: &str,
    ) -> Result<Option<Self>> {
        let mut layers = vec![];
        for i in 0.. {
            let (Some(w), Some(b)) = (
                arrays.get(format!("{prefix}.layers.{i}.weight").as_str()),
                arrays.get(format!("{prefix}.layers.{i}.bias").as_str()),
            ) else {
                break;
            };
            // A file's shape is input: one that is not two numbers, or whose product
            // overflows, is corrupt rather than a panic or a wrapped size.
            let &[d_in, d_out] = w.shape.as_slice() else {
                return Err(Error::corrupt(
                    "model file",
                    format!(
                        "{prefix} layer {i}'s weight has shape {:?}, not two numbers",
                        w.shape
                    ),
                ));
            };
            if b.values.len() != d_out || d_in.checked_mul(d_out) != Some(w.values.len()) {
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
    pub fn jet<'a>(&self, a: &'a Arena, input: &Activations<'a>) -> Activations<'a> {
        let last = self.layers.len() - 1;
        let mut x: Option<Activations> = None;
        for (l, (_, d_out, w, b)) in self.layers.iter().enumerate() {
            let mut z = x.as_ref().unwrap_or(input).linear(a, w, b, *d_out);
            if l != last {
                z.tanh(a);
            }
            x = Some(z);
        }
        x.expect("an MLP has layers")
    }
}

/// A batch's network inputs as a jet: `rows` states of `width` inputs, input j of state b
/// `value(b, j)` with its outer tangents; with `inner_scale`, input k also gets the inner
/// tangent ∂x_k/∂q_k = inner_scale[k].
pub(super) fn input_jet<'a, S: Lanes>(
    a: &'a Arena,
    (rows, width): (usize, usize),
    value: impl Fn(usize, usize) -> S,
    inner_scale: Option<&[f64]>,
    outer: usize,
) -> Activations<'a> {
    let inner = inner_scale.map_or(0, <[f64]>::len);
    let mut jet = Activations::zeros(a, rows, width, inner, outer);
    for b in 0..rows {
        for j in 0..width {
            value(b, j).write(&mut jet, b, 0, j);
        }
        for (k, &s) in inner_scale.unwrap_or(&[]).iter().enumerate() {
            jet.set(0, k + 1, b, k, s);
        }
    }
    jet
}

/// The networks' input from q with ∂/∂q in the tangent directions (inner tangents, when
/// `inner`) when some joint is not a plain coordinate: standardized q, with (sin q, cos q) in
/// place of an angle and (cos θ, sin θ) for a rotation (`Scaling::q_features_into`). Their
/// tangents depend on the sample and carry outer tangents of their own (the second
/// derivatives a linearization needs).
pub(super) fn periodic_q_jet<'a, S: Lanes>(
    a: &'a Arena,
    x: &Rows<S>,
    sc: &Scaling,
    space: &Space,
    inner: bool,
    outer: usize,
) -> Activations<'a> {
    let inner_dirs = if inner { x.nv } else { 0 };
    let width = space.q_features();
    let mut jet = Activations::zeros(a, x.len(), width, inner_dirs, outer);
    let mut features = AVec::with_capacity_in(width, a);
    for b in 0..x.len() {
        // The features and their ∂/∂q as the fused step builds them, written into the jet, a
        // group of directions at a time.
        features.clear();
        sc.q_features_into(x.q(b), space, 0..0, &mut features);
        for (j, f) in features.iter().enumerate() {
            f.v.write(&mut jet, b, 0, j);
        }
        for dirs in groups::<S>(inner_dirs) {
            features.clear();
            sc.q_features_into(x.q(b), space, dirs.clone(), &mut features);
            for (j, f) in features.iter().enumerate() {
                for k in 0..f.dirs() {
                    if let Some(t) = f.tangent(k) {
                        t.write(&mut jet, b, dirs.start + k + 1, j);
                    }
                }
            }
        }
    }
    jet
}

/// The networks' input from [q, v, u] (u only `with_u`) with angles or rotations (see
/// [`periodic_q_jet`]).
pub(super) fn periodic_full_jet<'a, S: Lanes>(
    a: &'a Arena,
    x: &Rows<S>,
    with_u: bool,
    sc: &Scaling,
    space: &Space,
    outer: usize,
) -> Activations<'a> {
    let q_part = periodic_q_jet(a, x, sc, space, false, outer);
    let m = if with_u { x.m } else { 0 };
    let mut jet = Activations::zeros(a, x.len(), q_part.width + x.nv + m, 0, outer);
    for o in 0..=outer {
        for b in 0..q_part.batch {
            for j in 0..q_part.width {
                jet.set(o, 0, b, j, q_part.at(o, 0, b, j));
            }
        }
    }
    for b in 0..x.len() {
        let rest = (x.qd(b).iter().zip(sc.qdot_mean.iter().zip(&sc.qdot_std)))
            .chain((x.u(b)[..m].iter()).zip(sc.u_mean.iter().zip(&sc.u_std)))
            .map(|(x, (m, s))| x.shift(-m).scale(1.0 / s));
        for (j, v) in rest.enumerate() {
            v.write(&mut jet, b, 0, q_part.width + j);
        }
    }
    jet
}

/// The networks' outputs as the assembly reads them.
pub(super) struct JetNets<'a, S> {
    outs: &'a NetOutputs<'a>,
    /// The state of the batch read.
    row: usize,
    /// V's output and its q-derivatives, read once.
    potential: Option<(S, AVec<'a, S>)>,
}

impl<'a, S: Lanes> JetNets<'a, S> {
    /// State `row`'s outputs.
    pub(super) fn new(a: &'a Arena, outs: &'a NetOutputs<'a>, row: usize) -> Self {
        let read = |p: &Activations| {
            (
                S::read(p, row, 0, 0),
                (1..=p.inner).map(|i| S::read(p, row, i, 0)).collect_in(a),
            )
        };
        Self {
            outs,
            row,
            potential: outs.potential.as_ref().map(read),
        }
    }

    /// V's network output.
    pub(super) fn potential(&self) -> &S {
        &self.potential.as_ref().expect("potential outputs").0
    }
}

impl<S: Lanes> Networks<S> for JetNets<'_, S> {
    /// Output j with the jet's inner tangents `dirs`, each part a batch coordinate.
    fn mass(&self, j: usize, dirs: Range<usize>) -> Dual<S> {
        let jet = self.outs.mass.as_ref().expect("mass outputs");
        Dual::new(
            S::read(jet, self.row, 0, j),
            dirs.map(|k| Some(S::read(jet, self.row, k + 1, j))),
        )
    }
    fn potential_grad(&self, k: usize) -> S {
        let (v, grad) = self.potential.as_ref().expect("potential outputs");
        grad.get(k).cloned().unwrap_or_else(|| v.lift(0.0))
    }
    fn force(&self, j: usize) -> S {
        S::read(
            self.outs.force.as_ref().expect("force outputs"),
            self.row,
            0,
            j,
        )
    }
    fn damping(&self, j: usize) -> S {
        S::read(
            self.outs.damping.as_ref().expect("damping outputs"),
            self.row,
            0,
            j,
        )
    }
}

/// Network outputs of one batch, computed before the structure.
pub(super) struct NetOutputs<'a> {
    pub(super) mass: Option<Activations<'a>>,
    pub(super) potential: Option<Activations<'a>>,
    pub(super) force: Option<Activations<'a>>,
    pub(super) damping: Option<Activations<'a>>,
}

/// The structured model's networks on a batch. `q_jet(true)` is the standardized q with
/// its ∂/∂q directions; `full()` the standardized (q, q̇, u), `state()` (q, q̇).
pub(super) fn networks<'a>(
    a: &'a Arena,
    w: &Components,
    q_jet: impl Fn(bool) -> Activations<'a>,
    full: impl Fn() -> Activations<'a>,
    state: impl Fn() -> Activations<'a>,
) -> NetOutputs<'a> {
    let (mass_net, potential_net) = (w.mass_net(), w.potential_net());
    // M's and V's networks both read q with its ∂/∂q directions: one input jet for both.
    let q_in = (mass_net.is_some() || potential_net.is_some()).then(|| q_jet(true));
    let q_in = || q_in.as_ref().expect("built when a network reads it");
    NetOutputs {
        mass: mass_net.map(|net| net.jet(a, q_in())),
        potential: potential_net.map(|net| net.jet(a, q_in())),
        force: match &w.forces {
            Some(Forces::Net(net)) => Some(net.jet(a, &full())),
            Some(Forces::ControlAffine { b_net, .. } | Forces::Passive { b_net, .. }) => {
                Some(b_net.jet(a, &q_jet(false)))
            }
            _ => None,
        },
        damping: match &w.forces {
            Some(Forces::Passive { damping_net, .. }) => Some(damping_net.jet(a, &state())),
            _ => None,
        },
    }
}

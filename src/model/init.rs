//! A model's parameters at initialization, per component: networks drawn from one seeded rng
//! in the order M, V, F (a seed gives the same networks), constants at their neutral values.

use burn::tensor::Device;

use super::network::{Network, param};
use super::params::{
    ConstantAffine, ControlAffine, ForceParams, MassParams, Passive, PotentialParams, Values,
};
use crate::physics::mass_matrix;
use crate::physics::parts::{ForceSpec, MassSpec, PotentialSpec};
use crate::rng::Rng;

fn zeros(len: usize, device: &Device) -> Values {
    param(vec![0.0; len], [1, len], device)
}

/// The widths of the networks' inputs: q's (n, or more with angles as (sin, cos)) and
/// [q, q̇, u]'s.
pub(super) struct Widths {
    pub n: usize,
    pub m: usize,
    pub q_in: usize,
}

pub(super) fn mass(
    mass: &MassSpec,
    w: &Widths,
    rng: &mut Rng,
    device: &Device,
) -> Option<MassParams> {
    let tri = mass_matrix::outputs(w.n);
    match mass {
        MassSpec::Mlp { hidden } => Some(MassParams::Net(Network::init(
            w.q_in, hidden, tri, rng, device,
        ))),
        MassSpec::Constant => Some(MassParams::Constant(zeros(tri, device))),
        MassSpec::Template => None,
    }
}

pub(super) fn potential(
    v: &PotentialSpec,
    w: &Widths,
    rng: &mut Rng,
    device: &Device,
) -> Option<PotentialParams> {
    if let Some(hidden) = v.network() {
        return Some(PotentialParams::Net(network(v.is_residual())(
            w.q_in, hidden, 1, rng, device,
        )));
    }
    match v {
        PotentialSpec::Quadratic => Some(PotentialParams::Quadratic(zeros(
            mass_matrix::outputs(w.n),
            device,
        ))),
        _ => None,
    }
}

pub(super) fn forces(
    f: &ForceSpec,
    w: &Widths,
    rng: &mut Rng,
    device: &Device,
) -> Option<ForceParams> {
    let (n, m) = (w.n, w.m);
    if let Some(hidden) = f.network() {
        return Some(ForceParams::Net(network(f.is_residual())(
            w.q_in + n + m,
            hidden,
            n,
            rng,
            device,
        )));
    }
    match f {
        ForceSpec::ControlAffine { hidden } => Some(ForceParams::ControlAffine(ControlAffine {
            b_net: Network::init(w.q_in, hidden, n * m, rng, device),
            eta: zeros(n, device),
        })),
        // D's factor starts at PyTorch's initialization: damping from the start, which
        // training shapes (a zero factor would leave only ε).
        ForceSpec::Passive { hidden } => Some(ForceParams::Passive(Passive {
            b_net: Network::init(w.q_in, hidden, n * m, rng, device),
            damping_net: Network::init(w.q_in + n, hidden, n * (n + 1) / 2, rng, device),
        })),
        ForceSpec::ConstantAffine => {
            // B starts as the (rectangular) identity in scaled units.
            let b = (0..n * m)
                .map(|k| if k / m == k % m { 1.0 } else { 0.0 })
                .collect();
            Some(ForceParams::ConstantAffine(ConstantAffine {
                b_const: param(b, [1, n * m], device),
                eta: zeros(n, device),
            }))
        }
        ForceSpec::Mlp { .. } | ForceSpec::Template { .. } => None,
    }
}

type NetInit = fn(usize, &[usize], usize, &mut Rng, &Device) -> Network;

/// A residual's network starts at zero output; any other at PyTorch's initialization.
fn network(residual: bool) -> NetInit {
    if residual {
        Network::init_zero_output
    } else {
        Network::init
    }
}

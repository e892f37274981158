//! A model's parameters at initialization, per component: networks drawn from one seeded rng
//! in the order M, V, F (a seed gives the same networks), constants at their neutral values.

use burn::tensor::Device;

use super::mass_matrix;
use super::mlp::{Mlp, param};
use super::params::{
    ConstantAffine, ControlAffine, ForceParams, MassParams, PotentialParams, Values,
};
use super::spec::{ForceSpec, MassSpec, PotentialSpec};
use crate::rng::Rng;

fn zeros(len: usize, device: &Device) -> Values {
    param(vec![0.0; len], [1, len], device)
}

pub(super) fn mass(
    mass: &MassSpec,
    n: usize,
    rng: &mut Rng,
    device: &Device,
) -> Option<MassParams> {
    let tri = mass_matrix::outputs(n);
    match mass {
        MassSpec::Mlp { hidden } => Some(MassParams::Net(Mlp::init(n, hidden, tri, rng, device))),
        MassSpec::Constant => Some(MassParams::Constant(zeros(tri, device))),
        MassSpec::Template => None,
    }
}

pub(super) fn potential(
    v: &PotentialSpec,
    n: usize,
    rng: &mut Rng,
    device: &Device,
) -> Option<PotentialParams> {
    match v {
        PotentialSpec::Mlp { hidden } => {
            Some(PotentialParams::Net(Mlp::init(n, hidden, 1, rng, device)))
        }
        PotentialSpec::Quadratic => Some(PotentialParams::Quadratic(zeros(
            mass_matrix::outputs(n),
            device,
        ))),
        PotentialSpec::Template | PotentialSpec::Zero => None,
    }
}

pub(super) fn forces(
    f: &ForceSpec,
    n: usize,
    m: usize,
    rng: &mut Rng,
    device: &Device,
) -> Option<ForceParams> {
    match f {
        ForceSpec::Mlp { hidden } => Some(ForceParams::Net(Mlp::init(
            2 * n + m,
            hidden,
            n,
            rng,
            device,
        ))),
        ForceSpec::ControlAffine { hidden } => Some(ForceParams::ControlAffine(ControlAffine {
            b_net: Mlp::init(n, hidden, n * m, rng, device),
            eta: zeros(n, device),
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
        ForceSpec::Template => None,
    }
}

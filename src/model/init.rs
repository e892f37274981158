//! A model's parameters at initialization, per component: networks drawn from one seeded rng
//! in the order M, V, F (a seed gives the same networks), constants at their neutral values.

use burn::tensor::Device;

use super::Params;
use super::mass_matrix;
use super::mlp::{Mlp, param};
use super::spec::{ForceSpec, MassSpec, PotentialSpec};
use crate::rng::Rng;

impl Params {
    pub(super) fn empty() -> Self {
        Self {
            mass_net: None,
            mass_const: None,
            potential_net: None,
            potential_quad: None,
            force_net: None,
            b_net: None,
            b_const: None,
            eta: None,
            physical: None,
            naive: None,
        }
    }

    pub(super) fn init_mass(&mut self, mass: &MassSpec, n: usize, rng: &mut Rng, device: &Device) {
        let tri = mass_matrix::outputs(n);
        match mass {
            MassSpec::Mlp { hidden } => {
                self.mass_net = Some(Mlp::init(n, hidden, tri, rng, device));
            }
            MassSpec::Constant => self.mass_const = Some(param(vec![0.0; tri], [1, tri], device)),
            MassSpec::Template => {}
        }
    }

    pub(super) fn init_potential(
        &mut self,
        v: &PotentialSpec,
        n: usize,
        rng: &mut Rng,
        device: &Device,
    ) {
        let tri = mass_matrix::outputs(n);
        match v {
            PotentialSpec::Mlp { hidden } => {
                self.potential_net = Some(Mlp::init(n, hidden, 1, rng, device));
            }
            PotentialSpec::Quadratic => {
                self.potential_quad = Some(param(vec![0.0; tri], [1, tri], device));
            }
            PotentialSpec::Template | PotentialSpec::Zero => {}
        }
    }

    pub(super) fn init_forces(
        &mut self,
        f: &ForceSpec,
        n: usize,
        m: usize,
        rng: &mut Rng,
        device: &Device,
    ) {
        match f {
            ForceSpec::Mlp { hidden } => {
                self.force_net = Some(Mlp::init(2 * n + m, hidden, n, rng, device));
            }
            ForceSpec::ControlAffine { hidden } => {
                self.b_net = Some(Mlp::init(n, hidden, n * m, rng, device));
                self.eta = Some(param(vec![0.0; n], [1, n], device));
            }
            ForceSpec::ConstantAffine => {
                // B starts as the (rectangular) identity in scaled units.
                let b = (0..n * m)
                    .map(|k| if k / m == k % m { 1.0 } else { 0.0 })
                    .collect();
                self.b_const = Some(param(b, [1, n * m], device));
                self.eta = Some(param(vec![0.0; n], [1, n], device));
            }
            ForceSpec::Template => {}
        }
    }
}

//! A model's trainable values, per component, following its spec: the naive network, or the
//! mass matrix's, the potential's and the forces' own values plus the template's physical
//! parameters. A component kind with no values of its own (a template part, a zero potential)
//! is `None`. Every tensor is rank 2 (see `mlp`).
//!
//! Model files and checkpoints name each value (see [`names`]); the names are the file
//! format's, not Rust paths, so the layout here can change without changing the files.
//! The visiting order (mass, potential, forces, physical) is the order of the first
//! releases' fields, which checkpoints' optimizer state follows.

use burn::module::{Module, Param};
use burn::tensor::{Tensor, TensorData};

use super::network::Network;
use super::params_io::{NamedArray, export_as};

/// The file names of a model's values. A network's arrays are `<name>.layers.<i>.weight`
/// and `<name>.layers.<i>.bias`.
pub use crate::model::names;

/// A rank-2 trainable tensor.
pub type Values = Param<Tensor<2>>;

// A model holds one `Params`, and Burn has no `Module` for `Box`: the size gap costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Module, Debug)]
pub enum Params {
    /// One network from (q, q̇, u) to q̈.
    Naive(Network),
    Structured(Components),
}

#[derive(Module, Debug)]
pub struct Components {
    pub mass: Option<MassParams>,
    pub potential: Option<PotentialParams>,
    pub forces: Option<ForceParams>,
    /// The template's physical parameters, positive ones as logarithms, `[1, k]`; present
    /// when some part is white-box.
    pub physical: Option<Values>,
    /// `physical` holds the physical values themselves, not their trainable form: a model
    /// made from a template's equations, never trained (`names::PHYSICAL_VALUES`).
    pub physical_as_is: bool,
}

#[derive(Module, Debug)]
pub enum MassParams {
    /// The raw entries of L(q).
    Net(Network),
    /// Raw entries of a constant L, `[1, n(n+1)/2]`.
    Constant(Values),
}

#[derive(Module, Debug)]
pub enum PotentialParams {
    Net(Network),
    /// Entries of the symmetric K of ½qᵀKq, `[1, n(n+1)/2]` (row-major lower triangle).
    Quadratic(Values),
}

#[derive(Module, Debug)]
pub enum ForceParams {
    /// F(q, q̇, u).
    Net(Network),
    /// B_θ(q)u + ηq̇.
    ControlAffine(ControlAffine),
    /// Bu + ηq̇.
    ConstantAffine(ConstantAffine),
    /// B_θ(q)u − D_θ(q, q̇)q̇.
    Passive(Passive),
}

#[derive(Module, Debug)]
pub struct Passive {
    pub b_net: Network,
    /// [q, q̇] → the raw entries of D's factor.
    pub damping_net: Network,
}

#[derive(Module, Debug)]
pub struct ControlAffine {
    pub b_net: Network,
    /// Damping η, `[1, n]`.
    pub eta: Values,
}

#[derive(Module, Debug)]
pub struct ConstantAffine {
    /// B, `[1, n·m]` row-major.
    pub b_const: Values,
    /// Damping η, `[1, n]`.
    pub eta: Values,
}

impl Params {
    pub fn components(&self) -> Option<&Components> {
        match self {
            Params::Structured(c) => Some(c),
            Params::Naive(_) => None,
        }
    }

    /// Every value under its file name, in visiting order (what `params_io::import` reads).
    pub fn export(&self) -> Vec<NamedArray> {
        let c = match self {
            Params::Naive(net) => return export_as(names::NAIVE, net),
            Params::Structured(c) => c,
        };
        let mut out = vec![];
        match &c.mass {
            Some(MassParams::Net(net)) => out.extend(export_as(names::MASS_NET, net)),
            Some(MassParams::Constant(l)) => out.extend(export_as(names::MASS_CONST, l)),
            None => {}
        }
        match &c.potential {
            Some(PotentialParams::Net(net)) => out.extend(export_as(names::POTENTIAL_NET, net)),
            Some(PotentialParams::Quadratic(k)) => {
                out.extend(export_as(names::POTENTIAL_QUAD, k));
            }
            None => {}
        }
        match &c.forces {
            Some(ForceParams::Net(net)) => out.extend(export_as(names::FORCE_NET, net)),
            Some(ForceParams::ControlAffine(f)) => {
                out.extend(export_as(names::B_NET, &f.b_net));
                out.extend(export_as(names::ETA, &f.eta));
            }
            Some(ForceParams::ConstantAffine(f)) => {
                out.extend(export_as(names::B_CONST, &f.b_const));
                out.extend(export_as(names::ETA, &f.eta));
            }
            Some(ForceParams::Passive(f)) => {
                out.extend(export_as(names::B_NET, &f.b_net));
                out.extend(export_as(names::DAMPING_NET, &f.damping_net));
            }
            None => {}
        }
        if let Some(p) = &c.physical {
            let name = if c.physical_as_is {
                names::PHYSICAL_VALUES
            } else {
                names::PHYSICAL
            };
            out.extend(export_as(name, p));
        }
        out
    }
}

impl Params {
    /// These values with the template's raw physical values put back between `lower` and
    /// `upper` (one each per parameter; `physics::params::bounds`): the projection of
    /// projected gradient descent, after every optimizer step (docs/robots.md#joint-forces).
    pub fn projected(self, (lower, upper): &(Vec<f64>, Vec<f64>)) -> Self {
        let Params::Structured(mut c) = self else {
            return self;
        };
        if let Some(p) = c.physical.take() {
            let (id, t, _) = p.consume();
            let (autodiff, grad) = (t.is_autodiff(), t.is_require_grad());
            let inner = t.inner();
            let bound = |b: &[f64]| {
                Tensor::from_data(TensorData::new(b.to_vec(), inner.dims()), &inner.device())
            };
            let (lo, hi) = (bound(lower), bound(upper));
            let mut t = inner.max_pair(lo).min_pair(hi);
            if autodiff {
                t = Tensor::from_inner(t);
            }
            if grad {
                t = t.require_grad();
            }
            c.physical = Some(Param::initialized(id, t));
        }
        Params::Structured(c)
    }
}

impl Components {
    /// The raw entries of a constant L.
    pub fn mass_const(&self) -> Option<&Values> {
        match &self.mass {
            Some(MassParams::Constant(l)) => Some(l),
            _ => None,
        }
    }

    /// K of a quadratic potential.
    pub fn potential_quad(&self) -> Option<&Values> {
        match &self.potential {
            Some(PotentialParams::Quadratic(k)) => Some(k),
            _ => None,
        }
    }

    /// A constant B.
    pub fn b_const(&self) -> Option<&Values> {
        match &self.forces {
            Some(ForceParams::ConstantAffine(f)) => Some(&f.b_const),
            _ => None,
        }
    }

    /// The damping η of an affine force model.
    pub fn eta(&self) -> Option<&Values> {
        match &self.forces {
            Some(ForceParams::ControlAffine(f)) => Some(&f.eta),
            Some(ForceParams::ConstantAffine(f)) => Some(&f.eta),
            _ => None,
        }
    }
}

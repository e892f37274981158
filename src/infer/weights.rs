//! A trained model's values for f64 inference, per component as training holds them
//! (`model::params`), read from the model file by their names and checked against the spec:
//! a file missing a value its spec needs is corrupt at load, not a panic at the first call.

use std::collections::HashMap;

use super::Mlp64;
use crate::error::{Error, Result};
use crate::model::assembly::Values;
use crate::model::file::ModelFile;
use crate::model::params::names;
use crate::model::params_io::NamedArray;
use crate::model::spec::{ForceSpec, MassSpec, ModelSpec, PotentialSpec};

#[derive(Debug, Clone)]
pub(super) enum Weights {
    Naive(Mlp64),
    Structured(Components),
}

#[derive(Debug, Clone)]
pub(super) struct Components {
    pub(super) mass: Option<Mass>,
    pub(super) potential: Option<Potential>,
    pub(super) forces: Option<Forces>,
    /// Physical values (positive ones already exponentiated).
    pub(super) physical: Option<Vec<f64>>,
}

#[derive(Debug, Clone)]
pub(super) enum Mass {
    Net(Mlp64),
    Constant(Vec<f64>),
}

#[derive(Debug, Clone)]
pub(super) enum Potential {
    Net(Mlp64),
    Quadratic(Vec<f64>),
}

#[derive(Debug, Clone)]
pub(super) enum Forces {
    Net(Mlp64),
    ControlAffine { b_net: Mlp64, eta: Vec<f64> },
    ConstantAffine { b_const: Vec<f64>, eta: Vec<f64> },
}

impl Components {
    pub(super) fn mass_net(&self) -> Option<&Mlp64> {
        match &self.mass {
            Some(Mass::Net(net)) => Some(net),
            _ => None,
        }
    }

    pub(super) fn potential_net(&self) -> Option<&Mlp64> {
        match &self.potential {
            Some(Potential::Net(net)) => Some(net),
            _ => None,
        }
    }

    /// The non-network values, as the assembly reads them.
    pub(super) fn values(&self) -> Values<'_, f64> {
        Values {
            mass_const: match &self.mass {
                Some(Mass::Constant(l)) => Some(l),
                _ => None,
            },
            potential_quad: match &self.potential {
                Some(Potential::Quadratic(k)) => Some(k),
                _ => None,
            },
            b_const: match &self.forces {
                Some(Forces::ConstantAffine { b_const, .. }) => Some(b_const),
                _ => None,
            },
            eta: match &self.forces {
                Some(Forces::ControlAffine { eta, .. } | Forces::ConstantAffine { eta, .. }) => {
                    Some(eta)
                }
                _ => None,
            },
            physical: self.physical.as_deref(),
        }
    }
}

/// The file's arrays by name.
struct Arrays<'a>(HashMap<&'a str, &'a NamedArray>);

impl Arrays<'_> {
    fn net(&self, name: &str) -> Result<Mlp64> {
        Mlp64::from_arrays(&self.0, name)?.ok_or_else(|| missing(name))
    }

    fn values(&self, name: &str) -> Result<Vec<f64>> {
        self.0
            .get(name)
            .map(|a| a.values.clone())
            .ok_or_else(|| missing(name))
    }
}

fn missing(name: &str) -> Error {
    Error::corrupt(
        "model file",
        format!("the spec needs '{name}', which the file does not have"),
    )
}

impl Weights {
    pub(super) fn from_file(file: &ModelFile) -> Result<Self> {
        let arrays = Arrays(file.params.iter().map(|a| (a.name.as_str(), a)).collect());
        let ModelSpec::Structured {
            mass,
            potential,
            forces,
            template,
        } = &file.config.spec
        else {
            return Ok(Weights::Naive(arrays.net(names::NAIVE)?));
        };
        let physical = match template.filter(|_| !file.config.spec.white_box_parts().is_empty()) {
            Some(t) => Some(
                t.params()
                    .iter()
                    .zip(arrays.values(names::PHYSICAL)?)
                    .map(|(info, r)| if info.positive { r.exp() } else { r })
                    .collect(),
            ),
            None => None,
        };
        Ok(Weights::Structured(Components {
            mass: mass_weights(&arrays, mass)?,
            potential: potential_weights(&arrays, potential)?,
            forces: force_weights(&arrays, forces)?,
            physical,
        }))
    }

    /// Every network, for cost estimates.
    pub(super) fn networks(&self) -> Vec<&Mlp64> {
        let c = match self {
            Weights::Naive(net) => return vec![net],
            Weights::Structured(c) => c,
        };
        let force = match &c.forces {
            Some(Forces::Net(net) | Forces::ControlAffine { b_net: net, .. }) => Some(net),
            _ => None,
        };
        [c.mass_net(), c.potential_net(), force]
            .into_iter()
            .flatten()
            .collect()
    }
}

fn mass_weights(arrays: &Arrays, spec: &MassSpec) -> Result<Option<Mass>> {
    Ok(match spec {
        MassSpec::Mlp { .. } => Some(Mass::Net(arrays.net(names::MASS_NET)?)),
        MassSpec::Constant => Some(Mass::Constant(arrays.values(names::MASS_CONST)?)),
        MassSpec::Template => None,
    })
}

fn potential_weights(arrays: &Arrays, spec: &PotentialSpec) -> Result<Option<Potential>> {
    Ok(match spec {
        PotentialSpec::Mlp { .. } => Some(Potential::Net(arrays.net(names::POTENTIAL_NET)?)),
        PotentialSpec::Quadratic => {
            Some(Potential::Quadratic(arrays.values(names::POTENTIAL_QUAD)?))
        }
        PotentialSpec::Template | PotentialSpec::Zero => None,
    })
}

fn force_weights(arrays: &Arrays, spec: &ForceSpec) -> Result<Option<Forces>> {
    Ok(match spec {
        ForceSpec::Mlp { .. } => Some(Forces::Net(arrays.net(names::FORCE_NET)?)),
        ForceSpec::ControlAffine { .. } => Some(Forces::ControlAffine {
            b_net: arrays.net(names::B_NET)?,
            eta: arrays.values(names::ETA)?,
        }),
        ForceSpec::ConstantAffine => Some(Forces::ConstantAffine {
            b_const: arrays.values(names::B_CONST)?,
            eta: arrays.values(names::ETA)?,
        }),
        ForceSpec::Template => None,
    })
}

//! A trained model's values for f64 inference, per component as training holds them
//! (`model::params`), read from the model file by their names and checked against the spec:
//! a file missing a value its spec needs is corrupt at load, not a panic at the first call.

use std::collections::HashMap;

use super::Mlp64;
use crate::error::{Error, Result};
use crate::model::NamedArray;
use crate::model::file::ModelFile;
use crate::model::names;
use crate::model::spec::ModelSpec;
use crate::physics::assembly::Values;
use crate::physics::parts::{ForceSpec, MassSpec, PotentialSpec};

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
    Passive { b_net: Mlp64, damping_net: Mlp64 },
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

/// The file's arrays by name, read with the widths the model's dimensions require.
struct Arrays<'a> {
    by_name: HashMap<&'a str, &'a NamedArray>,
    n: usize,
    m: usize,
    /// Width of a network input from q (two per angle).
    q_in: usize,
}

impl Arrays<'_> {
    /// A network from `d_in` inputs through the spec's `hidden` widths to `d_out` outputs:
    /// every layer the shape the spec gives it, so that the file is the model its spec
    /// describes (and that listings, costs and limits read from the spec are the file's).
    fn net(&self, name: &str, d_in: usize, hidden: &[usize], d_out: usize) -> Result<Mlp64> {
        let net = Mlp64::from_arrays(&self.by_name, name)?.ok_or_else(|| missing(name))?;
        let widths: Vec<usize> = std::iter::once(d_in)
            .chain(hidden.iter().copied())
            .chain(std::iter::once(d_out))
            .collect();
        let spec = widths
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(" → ");
        let corrupt = |what: String| {
            Error::corrupt(
                "model file",
                format!("{name}: {what}; its spec's widths {spec} need that"),
            )
        };
        if net.layers.len() != widths.len() - 1 {
            return Err(corrupt(format!(
                "has {} layers where the spec has {}",
                net.layers.len(),
                widths.len() - 1
            )));
        }
        for (i, (layer, w)) in net.layers.iter().zip(widths.windows(2)).enumerate() {
            if (layer.0, layer.1) != (w[0], w[1]) {
                return Err(corrupt(format!(
                    "layer {i}'s weight is {}×{}, expected {}×{}",
                    layer.0, layer.1, w[0], w[1]
                )));
            }
        }
        Ok(net)
    }

    fn values(&self, name: &str, len: usize) -> Result<Vec<f64>> {
        let a = self.by_name.get(name).ok_or_else(|| missing(name))?;
        if a.values.len() != len {
            return Err(Error::corrupt(
                "model file",
                format!(
                    "'{name}' has {} values; the model needs {len}",
                    a.values.len()
                ),
            ));
        }
        Ok(a.values.clone())
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
        // M is nv × nv and F nv wide; the networks read q's features (`q_in`).
        let (n, m) = (file.config.nv(), file.config.m);
        let arrays = Arrays {
            by_name: file.params.iter().map(|a| (a.name.as_str(), a)).collect(),
            n,
            m,
            q_in: file.config.q_inputs(),
        };
        let (mass, potential, forces, template) = match &file.config.spec {
            ModelSpec::Naive { hidden } => {
                let full = file.config.full_inputs();
                return Ok(Weights::Naive(arrays.net(names::NAIVE, full, hidden, n)?));
            }
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                template,
            } => (mass, potential, forces, template),
        };
        let physical = match template
            .as_ref()
            .filter(|_| !file.config.spec.white_box_parts().is_empty())
        {
            // A model that trains nothing keeps the values as they are (`ModelFile::from_template`).
            Some(t) if arrays.by_name.contains_key(names::PHYSICAL_VALUES) => {
                Some(arrays.values(names::PHYSICAL_VALUES, t.params().len())?)
            }
            Some(t) => {
                Some(t.physical_from_raw(&arrays.values(names::PHYSICAL, t.params().len())?))
            }
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
    pub(super) fn networks(&self) -> impl Iterator<Item = &Mlp64> {
        let c = match self {
            Weights::Naive(net) => return [Some(net), None, None, None].into_iter().flatten(),
            Weights::Structured(c) => c,
        };
        let force = match &c.forces {
            Some(Forces::Net(net) | Forces::ControlAffine { b_net: net, .. }) => Some(net),
            Some(Forces::Passive { b_net, .. }) => Some(b_net),
            _ => None,
        };
        let damping = match &c.forces {
            Some(Forces::Passive { damping_net, .. }) => Some(damping_net),
            _ => None,
        };
        [c.mass_net(), c.potential_net(), force, damping]
            .into_iter()
            .flatten()
    }
}

fn mass_weights(a: &Arrays, spec: &MassSpec) -> Result<Option<Mass>> {
    let tri = a.n * (a.n + 1) / 2;
    Ok(match spec {
        MassSpec::Mlp { hidden } => Some(Mass::Net(a.net(names::MASS_NET, a.q_in, hidden, tri)?)),
        MassSpec::Constant => Some(Mass::Constant(a.values(names::MASS_CONST, tri)?)),
        MassSpec::Template => None,
    })
}

fn potential_weights(a: &Arrays, spec: &PotentialSpec) -> Result<Option<Potential>> {
    if let Some(hidden) = spec.network() {
        return Ok(Some(Potential::Net(a.net(
            names::POTENTIAL_NET,
            a.q_in,
            hidden,
            1,
        )?)));
    }
    Ok(match spec {
        PotentialSpec::Quadratic => Some(Potential::Quadratic(
            a.values(names::POTENTIAL_QUAD, a.n * (a.n + 1) / 2)?,
        )),
        _ => None,
    })
}

fn force_weights(a: &Arrays, spec: &ForceSpec) -> Result<Option<Forces>> {
    let (n, m) = (a.n, a.m);
    if let Some(hidden) = spec.network() {
        return Ok(Some(Forces::Net(a.net(
            names::FORCE_NET,
            a.q_in + n + m,
            hidden,
            n,
        )?)));
    }
    Ok(match spec {
        ForceSpec::ControlAffine { hidden } => Some(Forces::ControlAffine {
            b_net: a.net(names::B_NET, a.q_in, hidden, n * m)?,
            eta: a.values(names::ETA, n)?,
        }),
        ForceSpec::ConstantAffine => Some(Forces::ConstantAffine {
            b_const: a.values(names::B_CONST, n * m)?,
            eta: a.values(names::ETA, n)?,
        }),
        ForceSpec::Passive { hidden } => Some(Forces::Passive {
            b_net: a.net(names::B_NET, a.q_in, hidden, n * m)?,
            damping_net: a.net(names::DAMPING_NET, a.q_in + n, hidden, n * (n + 1) / 2)?,
        }),
        ForceSpec::Mlp { .. } | ForceSpec::Template { .. } => None,
    })
}

//! Model specifications: which form each component takes (docs/dynamics.md#state-and-components and the paper's
//! table of parameterizations), as JSON through serde or by the paper's names.

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::spec_json;
use crate::error::{Error, Result};
use crate::physics::params::Part;
use crate::physics::parts::{ForceSpec, MassSpec, PotentialSpec, structured_hidden};
use crate::physics::space::Space;
use crate::physics::templates::Template;
use crate::physics::urdf::UrdfTemplate;

pub const NAIVE_HIDDEN: [usize; 3] = [64, 64, 64];

fn naive_hidden() -> Vec<usize> {
    NAIVE_HIDDEN.to_vec()
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ModelSpec {
    /// The structured Lagrangian model.
    Structured {
        mass: MassSpec,
        potential: PotentialSpec,
        forces: ForceSpec,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        template: Option<Template>,
    },
    /// The naive baseline: an MLP [q, q̇, u] → q̈, integrated the same way.
    Naive {
        #[serde(default = "naive_hidden")]
        hidden: Vec<usize>,
    },
}

/// The paper's parameterizations (its table of models) plus the naive baseline.
pub const NAMED: [&str; 11] = [
    "MVF", "MVB", "MV", "VB", "MB", "M", "V", "B", "F", "W-B", "naive",
];

impl ModelSpec {
    /// A model by the paper's name ("MVF", …, "W-B", "naive"); a letter means that component
    /// is a network, the others are the template's white-box forms.
    pub fn named(name: &str, template: Option<Template>) -> Result<Self> {
        if name.eq_ignore_ascii_case("naive") {
            return Ok(ModelSpec::Naive {
                hidden: naive_hidden(),
            });
        }
        let letters = match name {
            "W-B" | "WB" | "white-box" => "",
            n if NAMED.contains(&n) => n,
            _ => {
                return Err(Error::invalid(
                    "model",
                    format!(
                        "unknown model '{name}'; expected one of {}",
                        NAMED.join(", ")
                    ),
                ));
            }
        };
        let nn = |c: char| letters.contains(c);
        let spec = ModelSpec::Structured {
            mass: if nn('M') {
                MassSpec::Mlp {
                    hidden: structured_hidden(),
                }
            } else {
                MassSpec::Template
            },
            potential: if nn('V') {
                PotentialSpec::Mlp {
                    hidden: structured_hidden(),
                }
            } else {
                PotentialSpec::TEMPLATE
            },
            forces: if nn('F') {
                ForceSpec::Mlp {
                    hidden: structured_hidden(),
                }
            } else if nn('B') {
                ForceSpec::ControlAffine {
                    hidden: structured_hidden(),
                }
            } else {
                ForceSpec::TEMPLATE
            },
            template,
        };
        spec.validate()?;
        Ok(spec)
    }

    /// Parses either a paper name or a JSON spec.
    pub fn parse(text: &str, template: Option<Template>) -> Result<Self> {
        let trimmed = text.trim();
        if trimmed.starts_with('{') {
            let value: Value = serde_json::from_str(trimmed)
                .map_err(|e| Error::invalid("model", format!("malformed JSON: {e}")))?;
            let mut spec: ModelSpec = serde_json::from_value(spec_json::normalize(&value)?)
                .map_err(|e| Error::invalid("model", format!("invalid model spec: {e}")))?;
            spec.set_template(template)?;
            spec.validate()?;
            Ok(spec)
        } else {
            Self::named(trimmed, template)
        }
    }

    /// Fills in the template given separately (a flag or a request field); a conflicting one
    /// is an error rather than a silent override.
    pub fn set_template(&mut self, t: Option<Template>) -> Result<()> {
        if let (ModelSpec::Structured { template, .. }, Some(t)) = (self, t) {
            match template {
                Some(existing) if *existing != t => {
                    return Err(Error::invalid(
                        "template",
                        format!(
                            "the spec names template '{}' but '{}' was given",
                            existing.name(),
                            t.name()
                        ),
                    ));
                }
                _ => *template = Some(t),
            }
        }
        Ok(())
    }

    /// The white-box parts of this spec.
    pub fn white_box_parts(&self) -> Vec<Part> {
        match self {
            ModelSpec::Naive { .. } => vec![],
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                ..
            } => {
                let mut parts = vec![];
                if *mass == MassSpec::Template {
                    parts.push(Part::Mass);
                }
                if matches!(potential, PotentialSpec::Template { .. }) {
                    parts.push(Part::Potential);
                }
                if matches!(forces, ForceSpec::Template { .. }) {
                    parts.push(Part::Forces);
                }
                parts
            }
        }
    }

    /// Training needs something to move: a network or a learned constant in some part, or a
    /// template parameter that a white-box part uses. Without one the loss is a constant,
    /// and its backward pass panicked ("requires a tracked autodiff tensor").
    pub fn check_trainable(&self) -> Result<()> {
        let ModelSpec::Structured {
            mass,
            potential,
            forces,
            template: Some(t),
        } = self
        else {
            // Naive is a network; a white-box part without a template is refused elsewhere.
            return Ok(());
        };
        let learned = self.has_network()
            || *mass == MassSpec::Constant
            || *potential == PotentialSpec::Quadratic
            || *forces == ForceSpec::ConstantAffine;
        let parts = self.white_box_parts();
        // A fixed parameter is known, not trained.
        let used = t
            .params()
            .iter()
            .any(|p| !p.fixed && p.used_by.iter().any(|u| parts.contains(u)));
        if learned || used {
            return Ok(());
        }
        let names: Vec<&str> = t
            .params()
            .iter()
            .map(|p| p.name.as_ref())
            .take(10)
            .collect();
        let why = match t.params().len() {
            0 => "has no parameters".to_string(),
            k => format!(
                "has {k} ({}{}) that none of the white-box parts uses or that are fixed",
                names.join(", "),
                if k > names.len() { ", …" } else { "" }
            ),
        };
        Err(Error::invalid(
            "template",
            format!(
                "no trainable parameter: the model has no network or learned constant, and \
                 template '{}' {why}; give it a parameter they use, or choose a model with a \
                 network (e.g. \"MVF\")",
                t.name()
            ),
        ))
    }

    /// Whether some part is a network (a residual included).
    pub fn has_network(&self) -> bool {
        match self {
            ModelSpec::Naive { .. } => true,
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                ..
            } => {
                matches!(mass, MassSpec::Mlp { .. })
                    || potential.network().is_some()
                    || forces.network().is_some()
                    || matches!(
                        forces,
                        ForceSpec::ControlAffine { .. } | ForceSpec::Passive { .. }
                    )
            }
        }
    }

    /// The URDF template whose multibody algorithms give this model's q̈ (its M is the
    /// template's), and whether they include gravity (its V is the template's too; otherwise
    /// the model's own V stands in for it).
    pub fn multibody(&self) -> Option<(&UrdfTemplate, bool)> {
        let ModelSpec::Structured {
            mass: MassSpec::Template,
            potential,
            template: Some(Template::Urdf(t)),
            ..
        } = self
        else {
            return None;
        };
        Some((t, matches!(potential, PotentialSpec::Template { .. })))
    }

    /// The bound of a URDF robot's effort delay, when it has one (`urdf::delay`).
    pub fn effort_delay(&self) -> Option<f64> {
        match self.template()? {
            Template::Urdf(u) => u.doc.effort_delay,
            _ => None,
        }
    }

    pub fn template(&self) -> Option<&Template> {
        match self {
            ModelSpec::Structured { template, .. } => template.as_ref(),
            ModelSpec::Naive { .. } => None,
        }
    }

    /// Structural checks that need no data: a white-box part needs a template, hidden sizes
    /// are positive.
    pub fn validate(&self) -> Result<()> {
        let hidden_ok = |h: &[usize], field: &str| -> Result<()> {
            if h.contains(&0) || h.len() > 16 || h.iter().any(|&w| w > 4096) {
                return Err(Error::invalid(
                    field,
                    "hidden sizes must be 1..=4096 wide and at most 16 layers",
                ));
            }
            Ok(())
        };
        match self {
            ModelSpec::Naive { hidden } => hidden_ok(hidden, "model.hidden"),
            ModelSpec::Structured {
                mass,
                potential,
                forces,
                template,
            } => {
                if let MassSpec::Mlp { hidden } = mass {
                    hidden_ok(hidden, "model.mass.hidden")?;
                }
                let at = |part: &str, residual: bool| {
                    format!(
                        "model.{part}{}.hidden",
                        if residual { ".residual" } else { "" }
                    )
                };
                if let Some(hidden) = potential.network() {
                    hidden_ok(hidden, &at("potential", potential.is_residual()))?;
                }
                if let Some(hidden) = forces.network() {
                    hidden_ok(hidden, &at("forces", forces.is_residual()))?;
                }
                if let ForceSpec::ControlAffine { hidden } | ForceSpec::Passive { hidden } = forces
                {
                    hidden_ok(hidden, "model.forces.hidden")?;
                }
                let parts = self.white_box_parts();
                if template.is_none() && !parts.is_empty() {
                    let names: Vec<&str> = parts.iter().map(|p| part_name(*p)).collect();
                    return Err(Error::invalid(
                        "template",
                        format!(
                            "white-box component(s) {} need a template (one of {})",
                            names.join(", "),
                            Template::ALL.map(|t| t.name().to_string()).join(", ")
                        ),
                    ));
                }
                Ok(())
            }
        }
    }

    /// Checks the spec against a dataset's dimensions.
    /// The spec fits data on this configuration space with m inputs: its template's sizes
    /// are the data's, and a quadratic potential ½ qᵀKq reads q as numbers (a flat space).
    pub fn check_dims(&self, space: &Space, m: usize) -> Result<()> {
        let (nq, nv) = (space.nq(), space.nv());
        if let Some(t) = self.template()
            && (t.nq() != nq || t.n() != nv || t.m() != m)
        {
            return Err(Error::invalid(
                "template",
                format!(
                    "template '{}' has nq = {}, nv = {}, m = {} but the data has nq = {nq}, \
                     nv = {nv}, m = {m}",
                    t.name(),
                    t.nq(),
                    t.n(),
                    t.m()
                ),
            ));
        }
        if let ModelSpec::Structured {
            potential: PotentialSpec::Quadratic,
            ..
        } = self
            && !space.is_flat()
        {
            return Err(Error::invalid(
                "spec.potential",
                "a quadratic potential ½ qᵀKq needs every joint to be one number (nq = nv)",
            ));
        }
        Ok(())
    }
}

pub fn part_name(p: Part) -> &'static str {
    match p {
        Part::Mass => "mass",
        Part::Potential => "potential",
        Part::Forces => "forces",
    }
}

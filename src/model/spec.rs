//! Model specifications: which form each component takes (design.md §2 and the paper's
//! table of parameterizations), as JSON through serde or by the paper's names.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

use super::templates::{Part, Template};
use crate::error::{Error, Result};

pub const STRUCTURED_HIDDEN: [usize; 3] = [32, 32, 32];
pub const NAIVE_HIDDEN: [usize; 3] = [64, 64, 64];

fn structured_hidden() -> Vec<usize> {
    STRUCTURED_HIDDEN.to_vec()
}

fn naive_hidden() -> Vec<usize> {
    NAIVE_HIDDEN.to_vec()
}

/// M(q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum MassSpec {
    /// Cholesky MLP: q → the n(n+1)/2 entries of L, diagonal through softplus + ε.
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// The template's analytic M(q) with trainable physical parameters.
    Template,
    /// A learned constant SPD matrix.
    Constant,
}

/// V(q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PotentialSpec {
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    Template,
    Zero,
    /// ½ qᵀKq with K symmetric and learned.
    Quadratic,
}

/// F(q, q̇, u).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ForceSpec {
    /// General MLP [q, q̇, u] → Rⁿ.
    Mlp {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// B_θ(q) u + η ∘ q̇ with B_θ an MLP q → n×m and η learned.
    ControlAffine {
        #[serde(default = "structured_hidden")]
        hidden: Vec<usize>,
    },
    /// Constant learned B and diagonal damping: B u + η ∘ q̇.
    ConstantAffine,
    Template,
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
                PotentialSpec::Template
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
                ForceSpec::Template
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
            let mut spec: ModelSpec = serde_json::from_value(normalize(&value)?)
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
                if *potential == PotentialSpec::Template {
                    parts.push(Part::Potential);
                }
                if *forces == ForceSpec::Template {
                    parts.push(Part::Forces);
                }
                parts
            }
        }
    }

    pub fn template(&self) -> Option<Template> {
        match self {
            ModelSpec::Structured { template, .. } => *template,
            ModelSpec::Naive { .. } => None,
        }
    }

    /// Structural checks that need no data: a white-box part needs a template, hidden sizes
    /// are positive.
    pub fn validate(&self) -> Result<()> {
        let hidden_ok = |h: &Vec<usize>, field: &str| -> Result<()> {
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
                if let PotentialSpec::Mlp { hidden } = potential {
                    hidden_ok(hidden, "model.potential.hidden")?;
                }
                if let ForceSpec::Mlp { hidden } | ForceSpec::ControlAffine { hidden } = forces {
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
                            Template::ALL.map(|t| t.name()).join(", ")
                        ),
                    ));
                }
                Ok(())
            }
        }
    }

    /// Checks the spec against a dataset's dimensions.
    pub fn check_dims(&self, n: usize, m: usize) -> Result<()> {
        if let Some(t) = self.template()
            && (t.n() != n || t.m() != m)
        {
            return Err(Error::invalid(
                "template",
                format!(
                    "template '{}' has n = {}, m = {} but the dataset has n = {n}, m = {m}",
                    t.name(),
                    t.n(),
                    t.m()
                ),
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

/// Each part's `type`s, as errors and the README name them.
const MASS_TYPES: &[&str] = &["mlp", "template", "constant"];
const POTENTIAL_TYPES: &[&str] = &["mlp", "template", "zero", "quadratic"];
const FORCE_TYPES: &[&str] = &["mlp", "control_affine", "constant_affine", "template"];
/// The types with hidden layers.
const WITH_HIDDEN: &[&str] = &["mlp", "control_affine"];

/// A JSON spec checked with errors a person can act on (the field, and the allowed values in
/// words, never a Rust type name), with its shorthands filled in: a part given as a string
/// is `{"type": …}`, and a spec without `kind` is structured.
fn normalize(v: &Value) -> Result<Value> {
    let obj = v.as_object().ok_or_else(|| {
        Error::invalid(
            "model",
            "must be a model name (MVF, …, naive) or a spec object such as \
             {\"mass\": \"mlp\", \"potential\": \"mlp\", \"forces\": \"mlp\"}",
        )
    })?;
    let kind = match obj.get("kind") {
        None => "structured",
        Some(Value::String(k)) if k == "structured" || k == "naive" => k.as_str(),
        Some(k) => {
            return Err(Error::invalid(
                "model.kind",
                format!("unknown kind {k}; expected \"structured\" or \"naive\""),
            ));
        }
    };
    let mut out = Map::new();
    out.insert("kind".into(), kind.into());
    if kind == "naive" {
        check_fields(
            obj,
            &["kind", "hidden"],
            "model",
            "a naive spec has kind and hidden",
        )?;
        if let Some(h) = obj.get("hidden") {
            out.insert("hidden".into(), hidden(h, "model.hidden")?);
        }
        return Ok(Value::Object(out));
    }
    check_fields(
        obj,
        &["kind", "mass", "potential", "forces", "template"],
        "model",
        "a structured spec has mass, potential, forces and template",
    )?;
    for (name, types) in [
        ("mass", MASS_TYPES),
        ("potential", POTENTIAL_TYPES),
        ("forces", FORCE_TYPES),
    ] {
        out.insert(name.into(), part(obj.get(name), name, types)?);
    }
    if let Some(t) = obj.get("template") {
        let name = t.as_str().ok_or_else(|| {
            Error::invalid(
                "model.template",
                "must be a template name such as \"pendulum\"",
            )
        })?;
        Template::parse(name).map_err(|e| Error::invalid("model.template", e.to_string()))?;
        out.insert("template".into(), t.clone());
    }
    Ok(Value::Object(out))
}

fn check_fields(obj: &Map<String, Value>, allowed: &[&str], at: &str, hint: &str) -> Result<()> {
    match obj.keys().find(|k| !allowed.contains(&k.as_str())) {
        Some(k) => Err(Error::invalid(
            format!("{at}.{k}"),
            format!("unknown field; {hint}"),
        )),
        None => Ok(()),
    }
}

/// One part: `"mlp"` or `{"type": "mlp", "hidden": [32, 32, 32]}`.
fn part(v: Option<&Value>, name: &str, types: &[&str]) -> Result<Value> {
    let at = format!("model.{name}");
    let allowed = types.join(", ");
    let v = v.ok_or_else(|| Error::invalid(&at, format!("is required: one of {allowed}")))?;
    let (ty, obj) = match v {
        Value::String(t) => (t.as_str(), None),
        Value::Object(o) => {
            let t = o.get("type").and_then(Value::as_str).ok_or_else(|| {
                Error::invalid(
                    format!("{at}.type"),
                    format!("is required: one of {allowed}"),
                )
            })?;
            (t, Some(o))
        }
        _ => {
            return Err(Error::invalid(
                &at,
                format!("must be a type name ({allowed}) or {{\"type\": …, \"hidden\": […]}}"),
            ));
        }
    };
    if !types.contains(&ty) {
        return Err(Error::invalid(
            format!("{at}.type"),
            format!("unknown type '{ty}'; expected one of {allowed}"),
        ));
    }
    let mut out = Map::new();
    out.insert("type".into(), ty.into());
    if let Some(o) = obj {
        let fields: &[&str] = if WITH_HIDDEN.contains(&ty) {
            &["type", "hidden"]
        } else {
            &["type"]
        };
        check_fields(
            o,
            fields,
            &at,
            &format!("a {ty} part has {}", fields.join(" and ")),
        )?;
        if let Some(h) = o.get("hidden") {
            out.insert("hidden".into(), hidden(h, &format!("{at}.hidden"))?);
        }
    }
    Ok(Value::Object(out))
}

fn hidden(v: &Value, at: &str) -> Result<Value> {
    let ok = v
        .as_array()
        .is_some_and(|a| a.iter().all(|w| w.as_u64().is_some_and(|w| w > 0)));
    if ok {
        Ok(v.clone())
    } else {
        Err(Error::invalid(
            at,
            format!(
                "must be a list of layer widths (positive integers) such as [32, 32, 32], got {v}"
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error_of(json: &str) -> (String, String) {
        match ModelSpec::parse(json, None) {
            Err(Error::Invalid { field, message }) => (field, message),
            other => panic!("expected an invalid-argument error, got {other:?}"),
        }
    }

    #[test]
    fn a_part_may_be_given_by_its_type_name() {
        let short = ModelSpec::parse(
            r#"{"mass": "mlp", "potential": "quadratic", "forces": "constant_affine"}"#,
            None,
        )
        .unwrap();
        let long = ModelSpec::parse(
            r#"{"kind": "structured", "mass": {"type": "mlp", "hidden": [32, 32, 32]},
                "potential": {"type": "quadratic"}, "forces": {"type": "constant_affine"}}"#,
            None,
        )
        .unwrap();
        assert_eq!(short, long);
    }

    #[test]
    fn errors_name_the_field_and_the_allowed_values_in_words() {
        let cases = [
            (
                r#"{"mass": "mpl", "potential": "mlp", "forces": "mlp"}"#,
                "model.mass.type",
                "mlp, template, constant",
            ),
            (
                r#"{"mass": {"type": "constant", "hidden": [8]}, "potential": "mlp", "forces": "mlp"}"#,
                "model.mass.hidden",
                "a constant part has type",
            ),
            (
                r#"{"mass": "mlp", "potential": "mlp"}"#,
                "model.forces",
                "mlp, control_affine, constant_affine, template",
            ),
            (
                r#"{"mass": "mlp", "potential": 3, "forces": "mlp"}"#,
                "model.potential",
                "mlp, template, zero, quadratic",
            ),
            (
                r#"{"mass": {"type": "mlp", "hidden": [32, -1]}, "potential": "mlp", "forces": "mlp"}"#,
                "model.mass.hidden",
                "positive integers",
            ),
            (
                r#"{"mass": "mlp", "potential": "mlp", "forces": "mlp", "damping": 1}"#,
                "model.damping",
                "mass, potential, forces and template",
            ),
            (
                r#"{"kind": "blackbox"}"#,
                "model.kind",
                "\"structured\" or \"naive\"",
            ),
            (
                r#"{"mass": "mlp", "potential": "mlp", "forces": "mlp", "template": "acrobot"}"#,
                "model.template",
                "double_pendulum",
            ),
        ];
        for (json, field, words) in cases {
            let (f, m) = error_of(json);
            assert_eq!(f, field, "{json}: {m}");
            assert!(m.contains(words), "{json}: {m}");
            for rust in ["MassSpec", "PotentialSpec", "ForceSpec", "enum", "variant"] {
                assert!(!m.contains(rust), "{json}: a Rust name leaks: {m}");
            }
        }
    }
}

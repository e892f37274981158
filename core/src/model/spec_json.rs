//! A JSON model spec checked before serde reads it, with errors a person can act on (the
//! field, and the allowed values in words, never a Rust type name), and its shorthands filled
//! in: a part given as a string is `{"type": …}`, and a spec without `kind` is structured.

use serde_json::{Map, Value};

use crate::error::{Error, Result};
use crate::physics::templates::Template;

/// Each part's `type`s, as errors and the README name them.
const MASS_TYPES: &[&str] = &["mlp", "template", "constant"];
const POTENTIAL_TYPES: &[&str] = &["mlp", "template", "zero", "quadratic"];
const FORCE_TYPES: &[&str] = &[
    "mlp",
    "control_affine",
    "constant_affine",
    "passive",
    "template",
];
/// The types with hidden layers.
const WITH_HIDDEN: &[&str] = &["mlp", "control_affine", "passive"];

/// The spec, checked and with its shorthands filled in.
pub(super) fn normalize(v: &Value) -> Result<Value> {
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
        let residual = ty == "template" && name != "mass";
        let fields: &[&str] = if WITH_HIDDEN.contains(&ty) {
            &["type", "hidden"]
        } else if residual {
            &["type", "residual"]
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
        if let Some(r) = o.get("residual").filter(|_| residual) {
            out.insert(
                "residual".into(),
                part(Some(r), &format!("{name}.residual"), &["mlp"])?,
            );
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
    use super::super::spec::ModelSpec;
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
                "mlp, control_affine, constant_affine, passive, template",
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

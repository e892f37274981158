//! The rules a formula template document's names and values follow (checked when it is read,
//! before its expressions are), and the checks of its M at the document's values.

use std::collections::BTreeMap;

use super::doc::{FormulaDoc, bad};
use crate::error::Result;
use crate::linalg::cholesky::factor_rows;
use crate::names::{NAME_MAX, name_problem, quoted_name};
use crate::physics::formula::{Names, reserved};
use crate::physics::params::physical_problem;

/// The template's name follows the rule of every name (`names::name_problem`).
pub(super) fn check_name(name: &str) -> Result<()> {
    if name.trim().is_empty() {
        return Err(bad("name", "must not be empty"));
    }
    name_problem(name).map_or(Ok(()), |m| Err(bad("name", m)))
}

/// Each parameter's value within the bounds of every physical value (`templates::
/// physical_problem`): a value that passed here used to fail at the first epoch instead.
pub(super) fn check_values(doc: &FormulaDoc) -> Result<()> {
    for (name, p) in &doc.parameters {
        if let Some(m) = physical_problem(p.value, p.positive) {
            return Err(bad(format!("parameters.{name}.value"), m));
        }
    }
    Ok(())
}

fn identifier(name: &str) -> bool {
    let mut c = name.chars();
    c.next()
        .is_some_and(|f| f.is_ascii_alphabetic() || f == '_')
        && c.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Names are identifiers, unique across coordinates, velocities, inputs and parameters, and
/// not a function or `pi`.
pub(super) fn check_names(doc: &FormulaDoc) -> Result<Names> {
    if doc.coordinates.is_empty() {
        return Err(bad("coordinates", "name at least one coordinate"));
    }
    let mut seen: BTreeMap<String, String> = BTreeMap::new();
    let groups = [
        ("coordinates", doc.coordinates.clone()),
        ("inputs", doc.inputs.clone()),
        ("parameters", doc.parameters.keys().cloned().collect()),
    ];
    for (group, names) in &groups {
        for (i, name) in names.iter().enumerate() {
            let usable = identifier(name) && name.len() <= NAME_MAX;
            // A parameter's field holds its name, which must then be a usable one.
            let field = match (*group, usable) {
                ("parameters", true) => format!("parameters.{name}"),
                ("parameters", false) => "parameters".to_string(),
                _ => format!("{group}[{i}]"),
            };
            if !usable {
                let why = if identifier(name) {
                    format!("is longer than {NAME_MAX} characters")
                } else {
                    "is not a name (letters, digits, _; not starting with a digit)".to_string()
                };
                return Err(bad(field, format!("'{}' {why}", quoted_name(name))));
            }
            if reserved(name) {
                return Err(bad(
                    field,
                    format!(
                        "'{name}' is a function or constant of the expressions; choose another name"
                    ),
                ));
            }
            let mut claim = |n: String, owner: String| -> Result<()> {
                if let Some(other) = seen.insert(n.clone(), owner) {
                    return Err(bad(
                        field.clone(),
                        format!("'{n}' is already the name of {other}"),
                    ));
                }
                Ok(())
            };
            claim(name.clone(), field.clone())?;
            if *group == "coordinates" {
                claim(format!("{name}_dot"), format!("the velocity of {field}"))?;
            }
        }
    }
    Ok(Names {
        coordinates: doc.coordinates.clone(),
        inputs: doc.inputs.clone(),
        parameters: doc.parameters.keys().cloned().collect(),
    })
}

/// The first (i, j), j < i, where M differs from Mᵀ beyond rounding.
pub(super) fn asymmetry(m: &[Vec<f64>]) -> Option<(usize, usize)> {
    (0..m.len())
        .flat_map(|i| (0..i).map(move |j| (i, j)))
        .find(|&(i, j)| {
            let (a, b) = (m[i][j], m[j][i]);
            (a - b).abs() > 1e-9 * a.abs().max(b.abs())
        })
}

/// Finite with a Cholesky factor whose diagonal is positive (plain f64: this runs on every
/// upload, and n³ dual numbers made a large document cost minutes).
pub(super) fn positive_definite(m: &[Vec<f64>]) -> bool {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return false;
    }
    factor_rows(m).is_ok()
}

//! Formula templates (docs/robots.md#formula-templates): a mechanism's M(q), V(q) and F(q, q̇, u) written as
//! expressions over named coordinates, velocities, inputs and parameters, checked once when
//! the document is read and then evaluated over [`Scalar`] like the built-in templates.

use std::borrow::Cow;

mod doc;
mod rules;

use doc::bad;
pub use doc::{FormulaDoc, ParamDoc};
use rules::{asymmetry, check_name, check_names, check_values, positive_definite};

use super::MAX_DOF;
use super::formula::{Budget, Expr, Names, Symbol, parse_within};
use super::params::{ParamInfo, Part};
use super::scalar::Scalar;
use crate::arena::{AVec, Arena, CollectIn};
use crate::error::Result;
use crate::rng::Rng;

/// A checked formula template with its expressions parsed.
#[derive(Debug, Clone, PartialEq)]
pub struct FormulaTemplate {
    pub doc: FormulaDoc,
    names: Names,
    params: Vec<ParamInfo>,
    mass: Vec<Vec<Expr>>,
    potential: Expr,
    forces: Vec<Expr>,
}

/// Points at which M is checked for symmetry and positive definiteness: q uniform in
/// (−π, π) (angles cover a turn; lengths of a few units cover typical mechanisms).
const CHECK_POINTS: usize = 16;

impl FormulaTemplate {
    /// Reads and checks a template document of at most [`MAX_DOF`] coordinates; errors name
    /// the field, and for an expression the character offset in it.
    pub fn parse(json: &str) -> Result<Self> {
        let de = &mut serde_json::Deserializer::from_str(json);
        let doc: FormulaDoc = serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            // "." is the whole document, "?" a syntax error before any field.
            let field = if path == "." || path == "?" {
                "template".to_string()
            } else {
                path
            };
            bad(field, e.into_inner())
        })?;
        Self::from_doc(doc, MAX_DOF)
    }

    /// Checks a document, cheapest checks first: its sizes (at most `max_dof` coordinates,
    /// its expressions within the document's node budget) before anything evaluates them.
    pub fn from_doc(doc: FormulaDoc, max_dof: usize) -> Result<Self> {
        if doc.kind != "formula" {
            return Err(bad(
                "kind",
                format!("expected \"formula\", got \"{}\"", doc.kind),
            ));
        }
        check_name(&doc.name)?;
        let n = doc.coordinates.len();
        if n > max_dof {
            return Err(bad(
                "coordinates",
                format!("{n} coordinates; this service takes at most {max_dof} (--max-dof)"),
            ));
        }
        let names = check_names(&doc)?;
        if !doc.periodic.is_empty() && doc.periodic.len() != n {
            return Err(bad(
                "periodic",
                format!(
                    "expected {n} values (one per coordinate) or none, got {}",
                    doc.periodic.len()
                ),
            ));
        }
        check_values(&doc)?;
        if doc.mass.len() != n {
            return Err(bad(
                "mass",
                format!(
                    "expected {n} rows (one per coordinate), got {}",
                    doc.mass.len()
                ),
            ));
        }
        let budget = &mut Budget::document();
        let mut mass = vec![];
        for (i, row) in doc.mass.iter().enumerate() {
            if row.len() != n {
                return Err(bad(
                    format!("mass[{i}]"),
                    format!("expected {n} entries, got {}", row.len()),
                ));
            }
            let row = row
                .iter()
                .enumerate()
                .map(|(j, text)| {
                    let field = format!("mass[{i}][{j}]");
                    expression(&field, text, &names, true, budget)
                })
                .collect::<Result<Vec<_>>>()?;
            mass.push(row);
        }
        let potential = expression("potential", &doc.potential, &names, true, budget)?;
        if doc.forces.len() != n {
            return Err(bad(
                "forces",
                format!(
                    "expected {n} entries (one per coordinate), got {}",
                    doc.forces.len()
                ),
            ));
        }
        let forces = doc
            .forces
            .iter()
            .enumerate()
            .map(|(i, text)| expression(&format!("forces[{i}]"), text, &names, false, budget))
            .collect::<Result<Vec<_>>>()?;
        let params = param_infos(&doc, &mass, &potential, &forces);
        let t = Self {
            doc,
            names,
            params,
            mass,
            potential,
            forces,
        };
        t.check_mass()?;
        Ok(t)
    }

    pub fn n(&self) -> usize {
        self.doc.coordinates.len()
    }

    pub fn m(&self) -> usize {
        self.doc.inputs.len()
    }

    /// Parameter names in training order.
    pub fn param_names(&self) -> &[String] {
        &self.names.parameters
    }

    /// The parameters in training order, with the parts that use them.
    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    /// The length of a part's programs: what evaluating the part costs per sample.
    pub fn nodes(&self, part: Part) -> usize {
        match part {
            Part::Mass => self.mass.iter().flatten().map(|e| e.ops().len()).sum(),
            Part::Potential => self.potential.ops().len(),
            Part::Forces => self.forces.iter().map(|e| e.ops().len()).sum(),
        }
    }

    /// The document's parameter values, in training order.
    pub fn defaults(&self) -> Vec<f64> {
        self.doc.parameters.values().map(|p| p.value).collect()
    }

    pub fn mass<S: Scalar>(&self, p: &[S], q: &[S]) -> Vec<Vec<S>> {
        let a = Arena::new();
        (self.mass_in(&a, p, q).iter())
            .map(|r| r.to_vec())
            .collect()
    }

    /// M(q), its rows and their operands in `a`.
    pub fn mass_in<'a, S: Scalar>(&self, a: &'a Arena, p: &[S], q: &[S]) -> AVec<'a, AVec<'a, S>> {
        let sym = |s: Symbol| match s {
            Symbol::Q(i) => q[i].clone(),
            Symbol::Param(i) => p[i].clone(),
            // The checks at reading keep velocities and inputs out of M.
            Symbol::QDot(_) | Symbol::U(_) => {
                unreachable!("checked: M depends on q and parameters")
            }
        };
        (self.mass.iter())
            .map(|row| row.iter().map(|e| e.eval_in(a, &sym, &q[0])).collect_in(a))
            .collect_in(a)
    }

    pub fn potential<S: Scalar>(&self, p: &[S], q: &[S]) -> S {
        self.potential_in(&Arena::new(), p, q)
    }

    /// V(q), its operands in `a`.
    pub fn potential_in<S: Scalar>(&self, a: &Arena, p: &[S], q: &[S]) -> S {
        let sym = |s: Symbol| match s {
            Symbol::Q(i) => q[i].clone(),
            Symbol::Param(i) => p[i].clone(),
            Symbol::QDot(_) | Symbol::U(_) => {
                unreachable!("checked: V depends on q and parameters")
            }
        };
        self.potential.eval_in(a, &sym, &q[0])
    }

    pub fn forces<S: Scalar>(&self, p: &[S], q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        self.forces_in(&Arena::new(), p, q, qd, u).to_vec()
    }

    /// F(q, q̇, u), in `a`.
    pub fn forces_in<'a, S: Scalar>(
        &self,
        a: &'a Arena,
        p: &[S],
        q: &[S],
        qd: &[S],
        u: &[S],
    ) -> AVec<'a, S> {
        let sym = |s: Symbol| match s {
            Symbol::Q(i) => q[i].clone(),
            Symbol::QDot(i) => qd[i].clone(),
            Symbol::U(i) => u[i].clone(),
            Symbol::Param(i) => p[i].clone(),
        };
        (self.forces.iter())
            .map(|e| e.eval_in(a, &sym, &q[0]))
            .collect_in(a)
    }

    /// M at the document's values must be symmetric (to 1e-9 relative) and positive definite
    /// at random configurations, and V finite there; a mistyped entry shows up here rather
    /// than as a failed job.
    fn check_mass(&self) -> Result<()> {
        let p = self.defaults();
        let mut rng = Rng::new(0x05EE_DF0A);
        for _ in 0..CHECK_POINTS {
            let q: Vec<f64> = (0..self.n())
                .map(|_| rng.uniform_in(-std::f64::consts::PI, std::f64::consts::PI))
                .collect();
            let m = self.mass(&p, &q);
            let at = format!("at q = {q:.3?} with the document's parameter values");
            if let Some((i, j)) = asymmetry(&m) {
                let (a, b) = (m[i][j], m[j][i]);
                return Err(bad(
                    format!("mass[{i}][{j}]"),
                    format!(
                        "M must be symmetric: mass[{i}][{j}] = {a} but mass[{j}][{i}] = {b} {at}"
                    ),
                ));
            }
            if !positive_definite(&m) {
                return Err(bad(
                    "mass",
                    format!("M must be finite and positive definite; it is not {at}"),
                ));
            }
            if !self.potential(&p, &q).is_finite() {
                return Err(bad("potential", format!("V is not finite {at}")));
            }
        }
        Ok(())
    }
}

/// Each parameter with the parts whose expressions name it.
fn param_infos(
    doc: &FormulaDoc,
    mass: &[Vec<Expr>],
    potential: &Expr,
    forces: &[Expr],
) -> Vec<ParamInfo> {
    let uses = |exprs: Vec<&Expr>, i: usize| {
        exprs
            .iter()
            .any(|e| e.symbols().iter().any(|(s, _)| *s == Symbol::Param(i)))
    };
    doc.parameters
        .iter()
        .enumerate()
        .map(|(i, (name, p))| {
            let mut used_by = vec![];
            if uses(mass.iter().flatten().collect(), i) {
                used_by.push(Part::Mass);
            }
            if uses(vec![potential], i) {
                used_by.push(Part::Potential);
            }
            if uses(forces.iter().collect(), i) {
                used_by.push(Part::Forces);
            }
            ParamInfo {
                name: Cow::Owned(name.clone()),
                default: p.value,
                positive: p.positive,
                min: None,
                max: None,
                fixed: p.fixed,
                used_by: Cow::Owned(used_by),
            }
        })
        .collect()
}

/// Parses one expression; `configuration` ones (M, V) may use only q and parameters.
fn expression(
    field: &str,
    text: &str,
    names: &Names,
    configuration: bool,
    budget: &mut Budget,
) -> Result<Expr> {
    let e = parse_within(text, names, budget).map_err(|e| bad(field, quoted(e, text)))?;
    if configuration
        && let Some((s, at)) = e
            .symbols()
            .into_iter()
            .find(|(s, _)| matches!(s, Symbol::QDot(_) | Symbol::U(_)))
    {
        let what = if matches!(s, Symbol::QDot(_)) {
            "a velocity"
        } else {
            "an input"
        };
        let name: String = text
            .chars()
            .skip(at)
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        return Err(bad(
            field,
            format!(
                "{what} '{name}' at offset {at}: {field} may use only coordinates and parameters"
            ),
        ));
    }
    Ok(e)
}

/// A parse error with the expression it is in, cut to a window around the error when the
/// expression is long (the error's offset still counts from its start).
fn quoted(e: super::formula::ParseError, text: &str) -> String {
    const WINDOW: usize = 60;
    if text.chars().count() <= 2 * WINDOW {
        return format!("{e} in \"{text}\"");
    }
    let from = e.offset.saturating_sub(WINDOW);
    let part: String = text.chars().skip(from).take(2 * WINDOW).collect();
    format!("{e} in \"…{part}…\" (from offset {from})")
}

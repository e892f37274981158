//! White-box system templates: analytic M(q), V(q) and F(q, q̇, u) with named physical
//! parameters, written once over [`Scalar`] so that the same equations serve training (the
//! tape's columns), simulation and inference (f64), and their q-derivatives (dual numbers).

use std::sync::Arc;

use super::formula_template::FormulaTemplate;
use super::multibody::crba;
use super::params::{ParamInfo, Part};
use super::scalar::Scalar;
use super::space::Space;
use super::urdf::template::{KIND as URDF, UrdfTemplate};
use crate::arena::{AVec, Arena, CollectIn, avec};
use crate::error::{Error, Result};

/// The kinds of template document.
pub const DOCUMENT_KINDS: [&str; 2] = ["formula", URDF];

/// A white-box system: one of the built-in ones, or a user's template document (a formula
/// template or a URDF robot), kept whole so that a model file that names it needs no other
/// file. Serialized as the built-in's name or as the document.
#[derive(Debug, Clone, PartialEq)]
pub enum Template {
    DoublePendulum,
    Pendulum,
    Cartpole,
    /// A rigid body in a vertical plane, its heading a unit complex number (nq = 4, nv = 3).
    PlanarBody,
    Formula(Arc<FormulaTemplate>),
    Urdf(Arc<UrdfTemplate>),
}

/// Evaluates a combination given a lookup of parameter values by name.
pub type CombinationFn = fn(&dyn Fn(&str) -> f64) -> f64;

/// A combination of parameters that the data can pin down (docs/dynamics.md#identifiability),
/// meaningful when every part in `needs` is white-box.
pub struct Combination {
    pub name: &'static str,
    pub needs: &'static [Part],
    pub eval: CombinationFn,
}

mod planar_body;
mod tables;

use tables::*;

impl Template {
    pub const ALL: [Template; 4] = [
        Template::DoublePendulum,
        Template::Pendulum,
        Template::Cartpole,
        Template::PlanarBody,
    ];

    pub fn name(&self) -> &str {
        match self {
            Template::DoublePendulum => "double_pendulum",
            Template::Pendulum => "pendulum",
            Template::Cartpole => "cartpole",
            Template::PlanarBody => "planar_body",
            Template::Formula(f) => &f.doc.name,
            Template::Urdf(u) => &u.doc.name,
        }
    }

    /// "builtin", or the document's kind.
    pub fn kind(&self) -> &'static str {
        match self {
            Template::Formula(_) => DOCUMENT_KINDS[0],
            Template::Urdf(_) => DOCUMENT_KINDS[1],
            _ => "builtin",
        }
    }

    /// Operations a part of a formula template evaluates per sample (0 for the others, whose
    /// cost the job budget's structure term covers).
    pub fn nodes(&self, part: Part) -> usize {
        match self {
            Template::Formula(f) => f.nodes(part),
            _ => 0,
        }
    }

    /// What reports say about which values the data determines, beyond `combinations`.
    pub fn identifiability_note(&self) -> Option<&'static str> {
        match self {
            Template::Urdf(_) => Some(super::urdf::template::IDENTIFIABILITY),
            _ => None,
        }
    }

    /// Physical values from the raw values the optimiser moves (any scalar): positive
    /// parameters are trained as logarithms; a URDF body's as its log-Cholesky factor.
    pub fn physical_from_raw<S: Scalar>(&self, raw: &[S]) -> Vec<S> {
        match self {
            Template::Urdf(u) => u.physical_from_raw(raw),
            _ => self
                .params()
                .iter()
                .zip(raw)
                .map(|(info, r)| if info.positive { r.exp() } else { r.clone() })
                .collect(),
        }
    }

    /// Raw values from physical ones (`physical_from_raw`'s inverse); an error names `init.<name>`
    /// (422 for a value below its parameter's bound).
    pub fn raw_from_physical(&self, values: &[f64]) -> Result<Vec<f64>> {
        for (info, &v) in self.params().iter().zip(values) {
            let field = || format!("init.{}", info.name);
            if !v.is_finite() {
                return Err(Error::invalid(field(), "must be finite"));
            }
            if let Some(message) = info.out_of_bounds(v) {
                return Err(Error::Unprocessable {
                    field: field(),
                    message,
                });
            }
            // A URDF body's mass has its own rule (`UrdfTemplate::raw`): a massless link is a
            // body the file may have.
            if info.positive && v <= 0.0 && !matches!(self, Template::Urdf(_)) {
                return Err(Error::invalid(field(), format!("must be > 0, got {v}")));
            }
        }
        match self {
            Template::Urdf(u) => u.raw_from_physical(values),
            _ => Ok(self
                .params()
                .iter()
                .zip(values)
                .map(|(info, &v)| if info.positive { v.ln() } else { v })
                .collect()),
        }
    }

    /// The coordinates the template marks as angles (empty: none). Built-in templates mark
    /// none: a run opts in with its own `periodic`.
    pub fn periodic(&self) -> Vec<bool> {
        match self {
            Template::Formula(f) => f.doc.periodic.clone(),
            Template::Urdf(u) => u.periodic(),
            _ => vec![],
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// A template by name, or an error (field "template") listing the known ones.
    pub fn parse(name: &str) -> Result<Self> {
        Self::from_name(name).ok_or_else(|| {
            Error::invalid(
                "template",
                format!(
                    "unknown template '{name}'; expected one of {}",
                    Self::ALL.map(|t| t.name().to_string()).join(", ")
                ),
            )
        })
    }

    /// The coordinates' names, one per velocity (a built-in's are q1, q2, …).
    pub fn coordinates(&self) -> Vec<String> {
        match self {
            Template::PlanarBody => ["x", "y", "theta"].map(String::from).to_vec(),
            Template::Formula(f) => f.doc.coordinates.clone(),
            Template::Urdf(u) => u.coordinates(),
            _ => (1..=self.n()).map(|i| format!("q{i}")).collect(),
        }
    }

    /// The inputs' names (a built-in's are u1, u2, …).
    pub fn inputs(&self) -> Vec<String> {
        match self {
            Template::Formula(f) => f.doc.inputs.clone(),
            Template::Urdf(u) => u.inputs(),
            _ => (1..=self.m()).map(|i| format!("u{i}")).collect(),
        }
    }

    /// The configuration space: its joints, with what each template marks as angles.
    pub fn space(&self) -> Space {
        match self {
            Template::PlanarBody => planar_body::space(),
            _ => Space::flat(self.n(), &self.periodic()),
        }
    }

    /// Configuration values.
    pub fn nq(&self) -> usize {
        self.space().nq()
    }

    /// Velocities (the degrees of freedom): M is nv × nv, F nv wide.
    pub fn n(&self) -> usize {
        match self {
            Template::DoublePendulum | Template::Cartpole => 2,
            Template::Pendulum => 1,
            Template::PlanarBody => 3,
            Template::Formula(f) => f.n(),
            Template::Urdf(u) => u.n(),
        }
    }

    /// Number of inputs.
    pub fn m(&self) -> usize {
        match self {
            Template::DoublePendulum => 2,
            Template::Pendulum | Template::Cartpole => 1,
            Template::PlanarBody => 3,
            Template::Formula(f) => f.m(),
            Template::Urdf(u) => u.m(),
        }
    }

    pub fn params(&self) -> &[ParamInfo] {
        match self {
            Template::DoublePendulum => DOUBLE_PENDULUM,
            Template::Pendulum => PENDULUM,
            Template::Cartpole => CARTPOLE,
            Template::PlanarBody => PLANAR_BODY,
            Template::Formula(f) => f.params(),
            Template::Urdf(u) => u.params(),
        }
    }

    /// The identifiable combinations graybox reports (none known for a user's template).
    pub fn combinations(&self) -> &'static [Combination] {
        match self {
            Template::DoublePendulum => DOUBLE_PENDULUM_COMBOS,
            Template::Pendulum => PENDULUM_COMBOS,
            Template::Cartpole => CARTPOLE_COMBOS,
            Template::PlanarBody => PLANAR_BODY_COMBOS,
            Template::Formula(_) | Template::Urdf(_) => &[],
        }
    }

    pub fn defaults(&self) -> Vec<f64> {
        self.params().iter().map(|p| p.default).collect()
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.params().iter().position(|p| p.name == name)
    }

    /// M(q) in f64 at physical values `p`, set up once for many q: a robot's by CRBA on its
    /// multibody model (docs/robots.md#multibody-dynamics), any other template's by `mass`.
    pub fn mass_at<'a>(&'a self, p: &'a [f64]) -> impl Fn(&[f64]) -> Vec<Vec<f64>> + 'a {
        let robot = match self {
            Template::Urdf(u) => Some(u.multibody_model(p, false)),
            _ => None,
        };
        move |q| match &robot {
            Some(model) => crba(model, q),
            None => self.mass(p, q),
        }
    }

    /// The symmetric mass matrix M(q), n×n.
    pub fn mass<S: Scalar>(&self, p: &[S], q: &[S]) -> Vec<Vec<S>> {
        let a = Arena::new();
        (self.mass_in(&a, p, q).iter())
            .map(|r| r.to_vec())
            .collect()
    }

    /// M(q) with its rows in `a`.
    pub fn mass_in<'a, S: Scalar>(&self, a: &'a Arena, p: &[S], q: &[S]) -> AVec<'a, AVec<'a, S>> {
        match self {
            Template::Formula(f) => f.mass_in(a, p, q),
            // The assembled robot's M is a reference path (its models run on the multibody
            // algorithms), so it keeps its own vectors.
            Template::Urdf(u) => (u.mass(p, q).into_iter())
                .map(|r| AVec::from_iter_in(r, a))
                .collect_in(a),
            Template::DoublePendulum => {
                let (m1, m2, l1, l2) = (&p[0], &p[1], &p[2], &p[3]);
                let i1 = (m1.clone() * l1.square()).scale(1.0 / 3.0);
                let i2 = (m2.clone() * l2.square()).scale(1.0 / 3.0);
                let c2 = q[1].cos();
                let m2l1l2c2 = m2.clone() * l1.clone() * l2.clone() * c2;
                let i11 = i1 + i2.clone() + m2.clone() * l1.square() + m2l1l2c2.clone();
                let i12 = i2.clone() + m2l1l2c2.scale(0.5);
                avec![in a; avec![in a; i11, i12.clone()], avec![in a; i12, i2]]
            }
            Template::Pendulum => {
                let (m, l) = (&p[0], &p[1]);
                avec![in a; avec![in a; (m.clone() * l.square()).scale(1.0 / 3.0)]]
            }
            Template::PlanarBody => planar_body::mass_in(a, p, q),
            Template::Cartpole => {
                let (mc, mp, l) = (&p[0], &p[1], &p[2]);
                let off = mp.clone() * l.clone() * q[1].cos();
                avec![in a;
                    avec![in a; mc.clone() + mp.clone(), off.clone()],
                    avec![in a; off, mp.clone() * l.square()],
                ]
            }
        }
    }

    /// The potential energy V(q).
    pub fn potential<S: Scalar>(&self, p: &[S], q: &[S]) -> S {
        self.potential_in(&Arena::new(), p, q)
    }

    /// V(q), any scratch in `a`.
    pub fn potential_in<S: Scalar>(&self, a: &Arena, p: &[S], q: &[S]) -> S {
        match self {
            Template::Formula(f) => f.potential_in(a, p, q),
            Template::Urdf(u) => u.potential(p, q),
            Template::DoublePendulum => {
                let (m1, m2, l1, l2, g) = (&p[0], &p[1], &p[2], &p[3], &p[4]);
                let c1 = q[0].cos();
                let c12 = (q[0].clone() + q[1].clone()).cos();
                let v1 = (m1.clone() * g.clone() * l1.clone() * c1.clone()).scale(-0.5);
                let v2 =
                    -(m2.clone() * g.clone() * (l1.clone() * c1 + (l2.clone() * c12).scale(0.5)));
                v1 + v2
            }
            Template::Pendulum => {
                let (m, l, g) = (&p[0], &p[1], &p[2]);
                (m.clone() * g.clone() * l.clone() * q[0].cos()).scale(-0.5)
            }
            Template::PlanarBody => planar_body::potential(p, q),
            Template::Cartpole => {
                let (mp, l, g) = (&p[1], &p[2], &p[3]);
                -(mp.clone() * g.clone() * l.clone() * q[1].cos())
            }
        }
    }

    /// The generalized forces F(q, q̇, u).
    pub fn forces<S: Scalar>(&self, p: &[S], q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        self.forces_in(&Arena::new(), p, q, qd, u).to_vec()
    }

    /// F(q, q̇, u) in `a`.
    pub fn forces_in<'a, S: Scalar>(
        &self,
        a: &'a Arena,
        p: &[S],
        q: &[S],
        qd: &[S],
        u: &[S],
    ) -> AVec<'a, S> {
        match self {
            Template::Formula(f) => f.forces_in(a, p, q, qd, u),
            Template::Urdf(t) => t.forces_in(a, p, q, qd, u),
            Template::DoublePendulum => {
                let (b1, b2, e1, e2) = (&p[5], &p[6], &p[7], &p[8]);
                avec![in a;
                    b1.clone() * u[0].clone() + e1.clone() * qd[0].clone(),
                    b2.clone() * u[1].clone() + e2.clone() * qd[1].clone(),
                ]
            }
            Template::Pendulum => {
                let (b, e) = (&p[3], &p[4]);
                avec![in a; b.clone() * u[0].clone() + e.clone() * qd[0].clone()]
            }
            Template::PlanarBody => planar_body::forces_in(a, p, q, qd, u),
            Template::Cartpole => {
                let (b, ex, eth) = (&p[4], &p[5], &p[6]);
                avec![in a;
                    b.clone() * u[0].clone() + ex.clone() * qd[0].clone(),
                    eth.clone() * qd[1].clone(),
                ]
            }
        }
    }
}

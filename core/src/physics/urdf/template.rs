//! A URDF template (docs/robots.md#urdf-robots): the robot's rigid-body M(q) and V(q) with each body's ten
//! inertial parameters, and joint forces F = S u − d∘q̇ − f∘tanh(q̇/ε).
//!
//! Three forms of the same values:
//! - physical (what `init`, `--set`, reports and the export use, `params()` order): per body
//!   `<link>.mass`, `.com_x|y|z`, `.ixx|ixy|ixz|iyy|iyz|izz` (about the centre of mass,
//!   link-frame axes); per joint `<joint>.damping`, `.friction`; then, when the robot has
//!   them, per coordinate `<joint>.armature` (docs/robots.md#armature). The template's
//!   equations take these.
//! - raw (what the optimiser moves): per body θ of the log-Cholesky pseudo-inertia
//!   (`inertia.rs`), ordered so that raw index k feeds physical index k's part (α ↔ mass,
//!   t ↔ centre of mass, the factor's d and s ↔ the six moments); per joint d and f (and the
//!   armatures) as they are. Every raw vector is a physical body.

use serde::{Deserialize, Serialize};

use super::parameters::{Groups, PER_BODY, PER_JOINT, params_of};
use super::tree::{JointKind, Tree};
use crate::error::{Error, Result};
use crate::names::name_problem;
use crate::physics::multibody::spatial::{
    V3, body_of_physical, of_physical, physical_of_raw, raw_order, standard_of_physical,
};
use crate::physics::multibody::{self, Inertial, crba_with, potential_energy_of};
use crate::physics::params::{ParamInfo, physical_problem};
use crate::physics::scalar::Scalar;

/// The template document (kept whole: a model file embeds it, and the export rewrites its
/// URDF text).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UrdfDoc {
    pub kind: String,
    /// The robot's name when absent.
    #[serde(default)]
    pub name: String,
    /// The URDF document.
    pub urdf: String,
    /// In the root link's frame, m/s².
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    /// The joints with an input, in coordinate order; absent: every movable joint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuated: Option<Vec<String>>,
    /// Joints that are angles besides the `continuous` ones.
    #[serde(default)]
    pub periodic: Vec<String>,
    /// ε of the Coulomb term tanh(q̇/ε), rad/s or m/s: a larger one is a smoother friction
    /// that an explicit integrator can step (`physics::stiffness`). Absent: `COULOMB_EPS`, as
    /// every document before the option meant (and then not written).
    #[serde(
        default = "default_coulomb_eps",
        skip_serializing_if = "is_default_eps"
    )]
    pub coulomb_eps: f64,
    /// Whether each coordinate has a trainable armature (rotor inertia reflected through its
    /// gear, on M's diagonal): set here, or by any joint's `<dynamics armature>` in the file
    /// (then set in the stored document). Absent: none, as before the option.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub armature: bool,
    /// Whether each input has a trainable gain g and offset o: the joint's force is g u + o
    /// for the logged effort u (a torque sensor's or a current's scale and bias,
    /// docs/robots.md#effort-gain-and-offset). Absent: u as it is.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub effort_gain: bool,
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub effort_offset: bool,
    /// The largest delay of the efforts behind the log's motion, seconds: with it the robot
    /// has a trainable `effort_delay` in [0, this] (docs/robots.md#effort-delay). Absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effort_delay: Option<f64>,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

fn default_coulomb_eps() -> f64 {
    COULOMB_EPS
}

fn is_default_eps(eps: &f64) -> bool {
    *eps == COULOMB_EPS
}

pub const KIND: &str = "urdf";

/// The most moving bodies whose base parameters a report lists: their QR grows as bodies³
/// (`graybox inspect` of a 64-joint chain: 3.2 s and 36 MB in all; the 256 of `--max-dof`
/// would take 64 times the QR's time and 16 times its memory per report).
pub const BASE_PARAMETERS_MAX_BODIES: usize = 64;

pub use super::settings::COULOMB_EPS;

/// What an identification can and cannot tell, said wherever a URDF model's values are shown.
pub const IDENTIFIABILITY: &str = "motion data determines only combinations of the inertial \
    parameters (the base parameters of the robot's regressor): values that move along an \
    unidentifiable direction fit the data equally well, so read the masses, centres of mass \
    and inertias as one consistent, physically realisable solution, not as measurements";

#[derive(Debug, Clone)]
pub struct UrdfTemplate {
    pub doc: UrdfDoc,
    pub tree: Tree,
    params: Vec<ParamInfo>,
    /// The coordinate each input drives.
    pub(super) actuated: Vec<usize>,
    periodic: Vec<bool>,
    /// The robot with its URDF's inertias and the document's gravity, built once: the
    /// kinematics that M and V over trainable values run on (its inertias never enter).
    robot: multibody::Model,
}

/// Everything but the document and the tree follows from them.
impl PartialEq for UrdfTemplate {
    fn eq(&self, o: &Self) -> bool {
        self.doc == o.doc && self.tree == o.tree
    }
}

fn bad(field: &str, message: impl Into<String>) -> Error {
    Error::Unprocessable {
        field: field.into(),
        message: message.into(),
    }
}

impl UrdfTemplate {
    /// A raw URDF document with every default.
    pub fn from_urdf(urdf: &str) -> Result<Self> {
        Self::from_urdf_within(urdf, crate::physics::MAX_DOF)
    }

    /// `from_urdf` for a service that takes at most `max_dof` coordinates.
    pub fn from_urdf_within(urdf: &str, max_dof: usize) -> Result<Self> {
        Self::from_doc(
            UrdfDoc {
                kind: KIND.into(),
                name: String::new(),
                urdf: urdf.into(),
                gravity: default_gravity(),
                actuated: None,
                periodic: vec![],
                coulomb_eps: COULOMB_EPS,
                armature: false,
                effort_gain: false,
                effort_offset: false,
                effort_delay: None,
            },
            max_dof,
        )
    }

    /// Checks a document (a robot of at most `max_dof` movable joints) and fills in its
    /// defaults (the name), so that the stored form is canonical.
    pub fn from_doc(mut doc: UrdfDoc, max_dof: usize) -> Result<Self> {
        if doc.kind != KIND {
            return Err(bad(
                "kind",
                format!("expected \"{KIND}\", got \"{}\"", doc.kind),
            ));
        }
        if let Some(m) = doc.gravity.iter().find_map(|&g| physical_problem(g, false)) {
            return Err(bad("gravity", format!("each component {m}")));
        }
        super::settings::check_coulomb_eps(doc.coulomb_eps)?;
        super::settings::check_effort_delay(doc.effort_delay)?;
        if let Some(m) = name_problem(&doc.name) {
            return Err(bad("name", m));
        }
        // The robot's name, when it is taken, passed the same rule in `Tree::parse`.
        let tree = Tree::parse(&doc.urdf, max_dof)?;
        doc.coulomb_eps = super::settings::coulomb_eps(doc.coulomb_eps, &tree)?;
        doc.armature |= tree.bodies.iter().any(|b| b.armature.is_some());
        if doc.name.trim().is_empty() {
            doc.name = tree.robot.clone();
        }
        if doc.name.trim().is_empty() {
            return Err(bad(
                "name",
                "must not be empty (the URDF's robot has no name)",
            ));
        }
        // The body of each coordinate, and the coordinate a joint's name names.
        let body = |i: usize| &tree.bodies[tree.coordinates[i]];
        let index = |field: &str, joint: &str| -> Result<usize> {
            if let Some(m) = tree
                .bodies
                .iter()
                .find(|b| b.joint == joint)
                .and_then(|b| b.mimic.as_ref())
            {
                return Err(bad(
                    field,
                    format!(
                        "'{joint}' is a mimic joint (it follows '{}'), not a coordinate",
                        m.joint
                    ),
                ));
            }
            (0..tree.coordinates.len())
                .find(|&i| body(i).joint == joint)
                .ok_or_else(|| {
                    let known: Vec<&str> = (0..tree.coordinates.len())
                        .map(|i| body(i).joint.as_str())
                        .collect();
                    bad(
                        field,
                        format!(
                            "'{joint}' is not a movable joint of the robot; its joints are {}",
                            known.join(", ")
                        ),
                    )
                })
        };
        let actuated = match &doc.actuated {
            None => (0..tree.coordinates.len()).collect(),
            Some(names) => {
                let mut idx = names
                    .iter()
                    .map(|j| index("actuated", j))
                    .collect::<Result<Vec<_>>>()?;
                idx.sort_unstable();
                if idx.windows(2).any(|w| w[0] == w[1]) {
                    return Err(bad("actuated", "names a joint twice"));
                }
                if idx.is_empty() {
                    return Err(bad("actuated", "must name at least one joint"));
                }
                idx
            }
        };
        // Canonical: in coordinate order.
        if doc.actuated.is_some() {
            doc.actuated = Some(actuated.iter().map(|&i| body(i).joint.clone()).collect());
        }
        let mut periodic: Vec<bool> = (0..tree.coordinates.len())
            .map(|i| body(i).kind == JointKind::Continuous)
            .collect();
        for j in &doc.periodic {
            let i = index("periodic", j)?;
            if body(i).kind == JointKind::Prismatic {
                return Err(bad(
                    "periodic",
                    format!("joint '{j}' is prismatic: a length is not an angle"),
                ));
            }
            periodic[i] = true;
        }
        // A negative damping or friction gives the robot energy (and Pinocchio's reader
        // refuses a negative friction): refused, not clamped, which would be another robot.
        for b in &tree.bodies {
            let armature = ("armature", b.armature.unwrap_or(0.0));
            for (what, v) in [("damping", b.damping), ("friction", b.friction), armature] {
                if v < 0.0 {
                    return Err(bad(
                        "urdf",
                        format!(
                            "joint '{}': <dynamics> {what} must be ≥ 0, got {v}",
                            b.joint
                        ),
                    ));
                }
            }
        }
        let inputs: Vec<&str> = actuated.iter().map(|&i| body(i).joint.as_str()).collect();
        let groups = Groups {
            armature: doc.armature,
            effort_gain: doc.effort_gain,
            effort_offset: doc.effort_offset,
            effort_delay: doc.effort_delay,
        };
        let params = params_of(&tree, groups, &inputs);
        let robot = tree.multibody(doc.gravity);
        Ok(Self {
            doc,
            tree,
            params,
            actuated,
            periodic,
            robot,
        })
    }

    /// Coordinates.
    pub fn n(&self) -> usize {
        self.tree.coordinates.len()
    }

    /// Moving bodies: the coordinates' and the mimic joints'.
    pub(super) fn nb(&self) -> usize {
        self.tree.bodies.len()
    }

    pub fn m(&self) -> usize {
        self.actuated.len()
    }

    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    pub fn periodic(&self) -> Vec<bool> {
        self.periodic.clone()
    }

    pub fn coordinates(&self) -> Vec<String> {
        (self.tree.coordinates.iter())
            .map(|&b| self.tree.bodies[b].joint.clone())
            .collect()
    }

    pub fn inputs(&self) -> Vec<String> {
        self.actuated
            .iter()
            .map(|&i| self.tree.bodies[self.tree.coordinates[i]].joint.clone())
            .collect()
    }

    /// Each input's `<limit effort>` (its joint's; None where the file gives none, or 0).
    pub fn effort_limits(&self) -> Vec<Option<f64>> {
        (self.actuated.iter())
            .map(|&i| self.tree.bodies[self.tree.coordinates[i]].effort)
            .collect()
    }

    /// Physical values from raw ones (any scalar; the tape's values in training).
    pub fn physical_from_raw<S: Scalar>(&self, raw: &[S]) -> Vec<S> {
        let mut out = Vec::with_capacity(raw.len());
        for b in 0..self.nb() {
            out.extend(physical_of_raw(&raw[b * PER_BODY..(b + 1) * PER_BODY]));
        }
        out.extend_from_slice(&raw[self.nb() * PER_BODY..]);
        out
    }

    /// Raw values from physical ones; an error (field `init.<link>.<…>`) names a body that is
    /// not physically realisable. A body that is only just not (a point mass, a thin rod) is
    /// regularised as the URDF's own values are.
    pub fn raw_from_physical(&self, physical: &[f64]) -> Result<Vec<f64>> {
        let mut out = Vec::with_capacity(physical.len());
        for (b, body) in self.tree.bodies.iter().enumerate() {
            let v = &physical[b * PER_BODY..(b + 1) * PER_BODY];
            if v[0] < 0.0 {
                return Err(Error::invalid(
                    format!("init.{}.mass", body.link),
                    format!("must be ≥ 0, got {}", v[0]),
                ));
            }
            let theta = of_physical(v).regularised().theta().map_err(|e| {
                let why = match e {
                    Error::Invalid { message, .. } => message,
                    other => other.to_string(),
                };
                Error::invalid(
                    format!("init.{}", body.link),
                    format!("link '{}': <inertial> {why}", body.link),
                )
            })?;
            out.extend(raw_order(&theta));
        }
        out.extend_from_slice(&physical[self.nb() * PER_BODY..]);
        Ok(out)
    }

    /// M(q) at physical values over any scalar (at fixed f64 values, `Template::mass_at`'s CRBA).
    pub fn mass<S: Scalar>(&self, p: &[S], q: &[S]) -> Vec<Vec<S>> {
        let bodies: Vec<_> = (p.chunks(PER_BODY).take(self.nb()))
            .map(body_of_physical)
            .collect();
        let mut m = crba_with(&self.robot, q, &bodies);
        for (c, a) in self.armature(p).iter().enumerate() {
            m[c][c] = m[c][c].clone() + a.clone();
        }
        m
    }

    /// V(q) at physical values over any scalar: the multibody model's potential energy with
    /// each body's m and h = m c.
    pub fn potential<S: Scalar>(&self, p: &[S], q: &[S]) -> S {
        let moments: Vec<(S, V3<S>)> = (p.chunks(PER_BODY).take(self.nb()))
            .map(|v| (v[0].clone(), [1, 2, 3].map(|k| v[0].clone() * v[k].clone())))
            .collect();
        potential_energy_of(&self.robot, q, &moments)
    }

    /// The robot at these physical values as the multibody algorithms take it
    /// (`multibody`); gravity only when the model's V is this template's (otherwise the
    /// model's own V stands in for it).
    pub fn multibody_model(&self, physical: &[f64], gravity: bool) -> multibody::Model {
        let bodies: Vec<Inertial> = (0..self.nb())
            .map(|b| self.link_inertial(physical, b))
            .collect();
        let g = if gravity { self.doc.gravity } else { [0.0; 3] };
        let model = self.tree.multibody_with(&bodies, g);
        match self.doc.armature {
            true => model.with_armature(self.armature(physical).to_vec()),
            false => model,
        }
    }

    /// π, every body's standard parameters then the armatures (`multibody::regressor`'s
    /// order), from physical values (any scalar: the tape's values in training).
    pub fn standard_parameters<S: Scalar>(&self, physical: &[S]) -> Vec<S> {
        (physical.chunks(PER_BODY).take(self.nb()))
            .flat_map(standard_of_physical)
            .chain(self.armature(physical).iter().cloned())
            .collect()
    }

    /// The physical values as URDF elements per link and joint (for the export).
    pub fn link_inertial(&self, physical: &[f64], body: usize) -> Inertial {
        of_physical(&physical[body * PER_BODY..(body + 1) * PER_BODY])
    }

    pub fn joint_dynamics(&self, physical: &[f64], body: usize) -> (f64, f64) {
        let k = self.nb() * PER_BODY + PER_JOINT * body;
        (physical[k], physical[k + 1])
    }
}

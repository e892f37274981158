//! Energy and power of a structured model (docs/energy.md), per state in f64 from the
//! model's own parts: kinetic T = ½ q̇ᵀM(q)q̇, potential V(q) up to its constant, the power
//! q̇ᵀF of the generalized forces, and M q̈ + c(q, q̇) + ∇V(q) = F term by term with F's named
//! parts. A URDF model's come from the multibody algorithms, as its `predict` does (CRBA for
//! M, RNEA for c and gravity, the articulated-body algorithm for q̈). An ensemble's are its
//! members' means, term by term, so that its split still sums.

use super::Evaluator;
use super::nets::JetNets;
use crate::error::{Error, Result};
use crate::model::spec::ModelSpec;
use crate::physics::assembly::{Columns, Structure};
use crate::physics::dynamics::{Tri, acceleration, coriolis, tri_t_mul};
use crate::physics::energy::PotentialValue;
use crate::physics::multibody::{
    self, crba, forward_dynamics, gravity_torques, kinetic_energy, potential_energy,
};

/// A batch's energies: per state `[B]`, per coordinate `[B, n]` row-major.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Energies {
    pub kinetic: Vec<f64>,
    pub potential: Vec<f64>,
    pub total: Vec<f64>,
    /// q̇ᵀF: the rate at which the generalized forces do work.
    pub power: Vec<f64>,
    /// M(q) q̈.
    pub inertial: Vec<f64>,
    /// c(q, q̇), the Coriolis and centrifugal term.
    pub coriolis: Vec<f64>,
    /// ∇V(q).
    pub gravity: Vec<f64>,
    /// F(q, q̇, u), the sum of `parts`.
    pub applied: Vec<f64>,
    pub parts: Vec<NamedPart>,
}

/// One named part of F for a batch, `[B, n]`.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedPart {
    pub name: &'static str,
    /// Named damping or friction by the spec (see `physics::energy::ForcePart`).
    pub dissipation: bool,
    pub values: Vec<f64>,
}

impl Energies {
    /// Refuses any figure that is not finite, naming `field` and the row: JSON has no
    /// non-finite numbers, so one would reach a caller as `null` (and the CLI printed it so,
    /// exiting 0, where the service refused).
    pub fn check_finite(&self, field: &str, n: usize) -> Result<()> {
        let per_state = [
            ("kinetic energy", &self.kinetic),
            ("potential energy", &self.potential),
            ("energy", &self.total),
            ("power", &self.power),
        ];
        for (what, v) in per_state {
            super::finite_rows(field, what, v, 1)?;
        }
        let per_coordinate = [
            ("inertial force M q̈", &self.inertial),
            ("Coriolis force", &self.coriolis),
            ("gravity force ∇V", &self.gravity),
            ("generalized force", &self.applied),
        ];
        let parts = self.parts.iter().map(|p| (p.name, &p.values));
        for (what, v) in per_coordinate.into_iter().chain(parts) {
            super::finite_rows(field, what, v, n)?;
        }
        Ok(())
    }
}

/// One state's figures.
struct Row {
    kinetic: f64,
    potential: f64,
    power: f64,
    inertial: Vec<f64>,
    coriolis: Vec<f64>,
    gravity: Vec<f64>,
    parts: Vec<NamedPart>,
}

impl<S: super::lanes::Lanes> PotentialValue<S> for JetNets<'_, S> {
    fn potential_value(&self) -> S {
        self.potential().clone()
    }
}

impl Evaluator {
    /// A naive model's network predicts q̈ directly: it has no M, V or F to speak of.
    pub fn check_energy(&self) -> Result<()> {
        match self.config.spec {
            ModelSpec::Structured { .. } => Ok(()),
            ModelSpec::Naive { .. } => Err(Error::FailedPrecondition(
                "a naive model has no energy: its network predicts q̈ directly, with no mass \
                 matrix, potential or generalized force to read T, V or the work of F from; \
                 train a structured model (MVF, MVB, a template) for this call"
                    .into(),
            )),
        }
    }

    /// How many named parts of F each state's answer has (0 for a naive model).
    pub fn force_part_count(&self) -> usize {
        match &self.config.spec {
            ModelSpec::Structured { forces, .. } => forces.part_count(),
            ModelSpec::Naive { .. } => 0,
        }
    }

    /// The energies of `[B, nq + nv]` states under `[B, m]` inputs, or `None` when `stop` says so
    /// (polled every state).
    pub fn energy_until(
        &self,
        x: &[f64],
        u: &[f64],
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<Energies>> {
        self.terms_until(x, u, None, stop)
    }

    /// Each state's energies and terms, M q̈ at the model's own q̈ or at `qdd` (`[B, nv]`)
    /// when given, or `None` when `stop` says so (polled every state).
    pub(super) fn terms_until(
        &self,
        x: &[f64],
        u: &[f64],
        qdd: Option<&[f64]>,
        stop: &dyn Fn() -> bool,
    ) -> Result<Option<Energies>> {
        self.check_energy()?;
        let (nx, nv, m) = (self.config.nx(), self.config.nv(), self.config.m);
        let members: Vec<&Evaluator> = match &self.members {
            Some(members) => members.iter().collect(),
            None => vec![self],
        };
        // Each state's figures go straight into the answer's arrays: a batch holds its
        // answer once, not a row of small vectors per state beside it.
        let mut out = Energies::default();
        for (k, (x, u)) in x.chunks(nx).zip(u.chunks(m)).enumerate() {
            if stop() {
                return Ok(None);
            }
            let qdd = qdd.map(|a| &a[k * nv..(k + 1) * nv]);
            let each: Vec<Row> = members.iter().map(|e| e.energy_row(x, u, qdd)).collect();
            out.push(mean_row(each));
        }
        Ok(Some(out))
    }

    fn energy_row(&self, x: &[f64], u: &[f64], qdd: Option<&[f64]>) -> Row {
        let (q, qd) = x.split_at(self.config.nq());
        let mut row = self
            .with_structure((q, qd, u), |s, nets, cols| match &self.multibody {
                Some(model) => multibody_row(model, s, nets, cols, qdd),
                None => assembled_row(s, nets, cols, qdd),
            })
            .expect("checked: a structured model");
        let applied = sum_parts(&row.parts, self.config.nv());
        row.power = qd.iter().zip(applied).map(|(v, f)| v * f).sum();
        row
    }
}

/// T and every term from the assembly: M = L Lᵀ with L's q-derivatives for c; M q̈ at the
/// model's q̈ or the one `given`.
fn assembled_row(
    s: &Structure<f64>,
    nets: &JetNets<f64>,
    x: &Columns<f64>,
    given: Option<&[f64]>,
) -> Row {
    let parts = named_parts(s, nets, x);
    let applied = sum_parts(&parts, s.n());
    let t = s.terms(nets, x);
    let l = &t.factor.l;
    let gravity = (t.grad_v.as_deref()).map_or_else(|| vec![0.0; s.n()], <[f64]>::to_vec);
    let qdd = match given {
        Some(qdd) => qdd.to_vec(),
        None => acceleration(&t.factor, t.grad_v.as_deref(), &applied, x.qd).to_vec(),
    };
    let w = tri_t_mul(l, x.qd);
    Row {
        power: 0.0,
        kinetic: 0.5 * w.iter().map(|v| v * v).sum::<f64>(),
        potential: s.potential_value(nets, x, true),
        inertial: lower_mul(l, &tri_t_mul(l, &qdd)),
        coriolis: coriolis(&t.factor, x.qd).to_vec(),
        gravity,
        parts,
    }
}

/// A robot's by the multibody algorithms: gravity is RNEA's at q̇ = q̈ = 0 plus the gradient
/// of whatever potential is not the template's (∇V′ = F − τ, τ the torques the algorithms take).
fn multibody_row(
    model: &multibody::Model,
    s: &Structure<f64>,
    nets: &JetNets<f64>,
    x: &Columns<f64>,
    given: Option<&[f64]>,
) -> Row {
    let (q, qd) = (x.q, x.qd);
    let parts = named_parts(s, nets, x);
    let applied = sum_parts(&parts, s.n());
    let tau = s.multibody_torques(nets, x);
    let qdd = match given {
        Some(qdd) => qdd.to_vec(),
        None => forward_dynamics(model, q, qd, &tau),
    };
    let m = crba(model, q);
    let rest = applied.iter().zip(&tau).map(|(f, t)| f - t);
    Row {
        power: 0.0,
        kinetic: kinetic_energy(model, q, qd),
        potential: potential_energy(model, q) + s.potential_value(nets, x, false),
        inertial: m
            .iter()
            .map(|row| row.iter().zip(&qdd).map(|(a, b)| a * b).sum())
            .collect(),
        coriolis: multibody::coriolis(model, q, qd),
        gravity: gravity_torques(model, q)
            .into_iter()
            .zip(rest)
            .map(|(g, r)| g + r)
            .collect(),
        parts,
    }
}

fn named_parts(s: &Structure<f64>, nets: &JetNets<f64>, x: &Columns<f64>) -> Vec<NamedPart> {
    (s.force_parts(nets, x).into_iter())
        .map(|p| NamedPart {
            name: p.name,
            dissipation: p.dissipation,
            values: p.values.to_vec(),
        })
        .collect()
}

fn sum_parts(parts: &[NamedPart], n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| parts.iter().map(|p| p.values[i]).sum())
        .collect()
}

/// L v for a lower-triangular L.
fn lower_mul(l: &Tri<f64>, v: &[f64]) -> Vec<f64> {
    (0..l.n)
        .map(|a| (0..=a).map(|b| l.get(a, b) * v[b]).sum())
        .collect()
}

/// The members' mean of each figure (a single model's own).
fn mean_row(mut rows: Vec<Row>) -> Row {
    if rows.len() == 1 {
        return rows.pop().expect("one row");
    }
    let k = rows.len() as f64;
    let mean = |f: &dyn Fn(&Row) -> &[f64]| -> Vec<f64> {
        let len = f(&rows[0]).len();
        (0..len)
            .map(|i| rows.iter().map(|r| f(r)[i]).sum::<f64>() / k)
            .collect()
    };
    let parts = (0..rows[0].parts.len())
        .map(|p| NamedPart {
            values: mean(&|r| &r.parts[p].values),
            ..rows[0].parts[p].clone()
        })
        .collect();
    Row {
        kinetic: rows.iter().map(|r| r.kinetic).sum::<f64>() / k,
        power: rows.iter().map(|r| r.power).sum::<f64>() / k,
        potential: rows.iter().map(|r| r.potential).sum::<f64>() / k,
        inertial: mean(&|r| &r.inertial),
        coriolis: mean(&|r| &r.coriolis),
        gravity: mean(&|r| &r.gravity),
        parts,
    }
}

impl Energies {
    /// One more state's figures.
    fn push(&mut self, row: Row) {
        let n = row.inertial.len();
        self.kinetic.push(row.kinetic);
        self.potential.push(row.potential);
        self.total.push(row.kinetic + row.potential);
        self.power.push(row.power);
        self.applied.extend(sum_parts(&row.parts, n));
        self.inertial.extend(row.inertial);
        self.coriolis.extend(row.coriolis);
        self.gravity.extend(row.gravity);
        if self.parts.is_empty() {
            self.parts = (row.parts.iter())
                .map(|p| NamedPart {
                    values: vec![],
                    ..p.clone()
                })
                .collect();
        }
        for (all, p) in self.parts.iter_mut().zip(row.parts) {
            all.values.extend(p.values);
        }
    }
}

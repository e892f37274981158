//! Simulated datasets from a template, with the paper's sampling: q ~ U(−r_q, r_q),
//! q̇ ~ U(−r_q̇, r_q̇), u ~ N(0, σ_u²), next state by RK4 of the true system.

mod trajectories;

pub use trajectories::{
    MAX_SUBSTEPS, MAX_TRANSITIONS, Recording, TrajectoryShape, double_pendulum_recorded,
    double_pendulum_trajectories, simulate_trajectories,
};

use crate::arena::Arena;
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::physics::dynamics::{constants, white_box_acceleration};
use crate::physics::integrator::{Integrator, States};
use crate::physics::multibody;
use crate::physics::space::{Joint, Space};
use crate::physics::stiffness;
use crate::physics::templates::Template;
use crate::records::Warning;
use crate::rng::Rng;

/// The code of the warning that a template's forces are too stiff for the step.
pub const STIFF_FORCES: &str = "stiff_forces";

/// `physics::stiffness::warning` of a template at values `p`, step `dt` and `integrator`
/// (looked at q = 0 and at `configurations`) as a warning.
pub fn stiffness_warning(
    t: &Template,
    p: &[f64],
    dt: f64,
    integrator: Integrator,
    configurations: &[Vec<f64>],
) -> Option<Warning> {
    stiffness::warning(t, p, dt, integrator, configurations)
        .map(|m| Warning::new(STIFF_FORCES, None, m))
}

/// The first `k` configurations q of a dataset, where a check looks besides q = 0.
pub fn configurations(ds: &Dataset, k: usize) -> Vec<Vec<f64>> {
    ds.q.chunks(ds.nq).take(k).map(<[f64]>::to_vec).collect()
}

/// The analytic system of a template at physical parameter values `p`, in f64: the "true"
/// system for simulation and the reference for tests.
pub struct TemplateSystem {
    pub template: Template,
    pub params: Vec<f64>,
    pub space: Space,
    /// A URDF robot for the multibody algorithms (docs/robots.md#multibody-dynamics).
    multibody: Option<multibody::Model>,
}

impl TemplateSystem {
    pub fn new(template: Template, params: Vec<f64>) -> Self {
        let multibody = match &template {
            Template::Urdf(t) => Some(t.multibody_model(&params, true)),
            _ => None,
        };
        Self {
            space: template.space(),
            template,
            params,
            multibody,
        }
    }

    pub fn acceleration(&self, q: &[f64], qd: &[f64], u: &[f64]) -> Vec<f64> {
        let tau = self.template.forces(&self.params, q, qd, u);
        if let Some(model) = &self.multibody {
            return multibody::with_data(|data| {
                data.forward_dynamics(model, q, qd, &tau);
                data.qdd.clone()
            });
        }
        let p = constants(&self.params);
        white_box_acceleration(
            &Arena::new(),
            &self.space,
            |q| self.template.mass(&p, q),
            |q| self.template.potential(&p, q),
            &tau,
            q,
            qd,
        )
        .to_vec()
    }

    /// Kinetic and potential energy (T, V).
    pub fn energy(&self, q: &[f64], qd: &[f64]) -> (f64, f64) {
        if let Some(model) = &self.multibody {
            return (
                multibody::kinetic_energy(model, q, qd),
                multibody::potential_energy(model, q),
            );
        }
        let m = self.template.mass(&self.params, q);
        let t = 0.5
            * (0..qd.len())
                .flat_map(|i| (0..qd.len()).map(move |j| (i, j)))
                .map(|(i, j)| qd[i] * m[i][j] * qd[j])
                .sum::<f64>();
        (t, self.template.potential(&self.params, q))
    }
}

#[derive(Debug, Clone)]
pub struct SimConfig {
    pub count: usize,
    pub seed: u64,
    pub dt: f64,
    pub q_range: f64,
    pub qdot_range: f64,
    pub u_std: f64,
    /// One σ per input instead of `u_std` for all (empty: `u_std`): a robot's distal joints
    /// are far lighter than its proximal ones and want far smaller torques.
    pub u_stds: Vec<f64>,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            count: 1024,
            seed: 0,
            dt: 0.01,
            q_range: std::f64::consts::PI,
            qdot_range: 10.0,
            u_std: 120.0,
            u_stds: vec![],
        }
    }
}

/// One step of the true system: x' = RK4(x, u).
pub fn true_step(
    sys: &TemplateSystem,
    x: &[f64],
    u: &[f64],
    dt: f64,
    integrator: Integrator,
) -> Vec<f64> {
    let nq = sys.space.nq();
    let states = States::new(&sys.space, 1);
    integrator.step(&states, &x.to_vec(), dt, |x: &Vec<f64>| {
        let (q, qd) = x.split_at(nq);
        let qdd = sys.acceleration(q, qd, u);
        qd.iter().chain(&qdd).copied().collect()
    })
}

pub fn simulate(template: &Template, params: Vec<f64>, cfg: &SimConfig) -> Result<Dataset> {
    if cfg.count == 0 {
        return Err(Error::invalid("count", "must be at least 1"));
    }
    cfg.check(template.m())?;
    let (space, m) = (template.space(), template.m());
    let (nq, nv) = (space.nq(), space.nv());
    let sys = TemplateSystem::new(template.clone(), params);
    let mut rng = Rng::new(cfg.seed);
    let mut arrays: [Vec<f64>; 5] = Default::default();
    for _ in 0..cfg.count {
        let q = sample_q(&space, &mut rng, cfg.q_range);
        let qd: Vec<f64> = (0..nv)
            .map(|_| rng.uniform_in(-cfg.qdot_range, cfg.qdot_range))
            .collect();
        let u = cfg.input(&mut rng, m);
        let x: Vec<f64> = q.iter().chain(&qd).copied().collect();
        let next = true_step(&sys, &x, &u, cfg.dt, Integrator::Rk4);
        arrays[0].extend(&q);
        arrays[1].extend(&qd);
        arrays[2].extend(&u);
        arrays[3].extend(&next[..nq]);
        arrays[4].extend(&next[nq..]);
    }
    Dataset::new(cfg.dt, (nq, nv), m, arrays)
}

/// A configuration with each joint's coordinate drawn uniformly in (−r, r), in joint order: a
/// rotation's angle θ drawn so and kept as (cos θ, sin θ).
pub(crate) fn sample_q(space: &Space, rng: &mut Rng, r: f64) -> Vec<f64> {
    let mut q = Vec::with_capacity(space.nq());
    for j in space.joints() {
        let v = rng.uniform_in(-r, r);
        match j {
            Joint::Real | Joint::Angle => q.push(v),
            Joint::Circle => q.extend([v.cos(), v.sin()]),
        }
    }
    q
}

impl SimConfig {
    /// The ranges and σs are usable for a system of `m` inputs.
    pub(crate) fn check(&self, m: usize) -> Result<()> {
        let cfg = self;
        for (name, v) in [
            ("dt", cfg.dt),
            ("q_range", cfg.q_range),
            ("qdot_range", cfg.qdot_range),
            ("u_std", cfg.u_std),
        ] {
            if !v.is_finite() || v < 0.0 || (name == "dt" && v == 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("must be a finite number ≥ 0 (dt > 0), got {v}"),
                ));
            }
        }
        if !cfg.u_stds.is_empty() && cfg.u_stds.len() != m {
            return Err(Error::invalid(
                "u_std",
                format!(
                    "expected one value or {m} (one per input), got {}",
                    cfg.u_stds.len()
                ),
            ));
        }
        if cfg.u_stds.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(Error::invalid("u_std", "must be finite numbers ≥ 0"));
        }
        Ok(())
    }

    /// One input u ~ N(0, σᵢ²).
    fn input(&self, rng: &mut Rng, m: usize) -> Vec<f64> {
        let sigma = |i: usize| self.u_stds.get(i).copied().unwrap_or(self.u_std);
        (0..m).map(|i| sigma(i) * rng.normal()).collect()
    }
}

/// Parses "k=v,k=v" into template parameter values, starting from the defaults; unknown
/// names are an error that lists the known ones.
pub fn parse_assignments(template: &Template, text: Option<&str>, field: &str) -> Result<Vec<f64>> {
    let mut values = template.defaults();
    for (name, v) in parse_pairs(text.unwrap_or(""), field)? {
        let i = template
            .index_of(&name)
            .ok_or_else(|| unknown_param(template, &name, field))?;
        values[i] = v;
    }
    // Values the template cannot take (a URDF body that is not physical, a negative mass)
    // are refused here, naming them under `field`.
    template.raw_from_physical(&values).map_err(|e| match e {
        Error::Invalid { field: f, message } => Error::Invalid {
            field: f.replacen("init", field, 1),
            message,
        },
        Error::Unprocessable { field: f, message } => Error::Unprocessable {
            field: f.replacen("init", field, 1),
            message,
        },
        other => other,
    })?;
    // A URDF's bodies are taken as the file has them, so a joint that moves only massless
    // links has no dynamics (a zero row of M, as Pinocchio's): said here, not as NaN in every
    // result. (A formula's M may be singular at a point of its own, as spherical coordinates'.)
    let q = vec![0.0; template.n()];
    let urdf = matches!(template, Template::Urdf(_));
    if let Some(i) = urdf
        .then(|| stiffness::singular_coordinate(&template.mass_at(&values)(&q)))
        .flatten()
    {
        return Err(Error::Unprocessable {
            field: "template".into(),
            message: format!(
                "M(q) is singular at q = 0 from coordinate '{}' on: a joint that moves no mass \
                 (a link without <inertial> and nothing with mass beyond it) has no dynamics; \
                 give it mass or make the joint fixed",
                template.coordinates()[i]
            ),
        });
    }
    Ok(values)
}

pub fn unknown_param(template: &Template, name: &str, field: &str) -> Error {
    let known: Vec<&str> = template.params().iter().map(|p| p.name.as_ref()).collect();
    Error::invalid(
        field,
        format!(
            "unknown parameter '{name}' for template '{}'; known: {}",
            template.name(),
            known.join(", ")
        ),
    )
}

/// "a=1,b=2" → [("a", 1.0), ("b", 2.0)].
pub fn parse_pairs(text: &str, field: &str) -> Result<Vec<(String, f64)>> {
    text.split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|kv| {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| Error::invalid(field, format!("expected name=value, got '{kv}'")))?;
            let v: f64 = v
                .trim()
                .parse()
                .map_err(|_| Error::invalid(field, format!("'{}' is not a number", v.trim())))?;
            if !v.is_finite() {
                return Err(Error::invalid(field, format!("{k} must be finite")));
            }
            Ok((k.trim().to_string(), v))
        })
        .collect()
}

//! `graybox simulate`: a transition dataset sampled from a white-box template.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use crate::error::{Error, Result};
use crate::model::file::write_atomic;
use crate::physics::integrator::Integrator;
use crate::sim::{self, SimConfig, parse_assignments};

#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// Template: double_pendulum, pendulum, cartpole, a template document's JSON file, or a
    /// URDF file.
    #[arg(long, visible_alias = "system")]
    pub template: String,
    /// Transitions, each from its own random state (the paper's sampling).
    #[arg(long, default_value_t = 1024, conflicts_with = "trajectories")]
    pub count: usize,
    /// Trajectories instead of independent transitions: this many, each from a random state
    /// (--q-range, --qdot-range) under inputs drawn every --hold steps (--u-std), written in
    /// the trajectory form (README "Dataset files").
    #[arg(long)]
    pub trajectories: Option<usize>,
    /// Transitions per trajectory.
    #[arg(long, default_value_t = 200, requires = "trajectories")]
    pub steps: usize,
    /// Steps each input of a trajectory is held for.
    #[arg(long, default_value_t = 10, requires = "trajectories")]
    pub hold: usize,
    /// RK4 steps of the true system per recorded step: the system evolves at dt / K and is
    /// recorded every dt, as a sensor samples a continuous system (1: RK4 at dt, which a
    /// model stepping RK4 at dt can match exactly).
    #[arg(long, default_value_t = 1, requires = "trajectories")]
    pub substeps: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The time step of each transition, seconds.
    #[arg(long, default_value_t = 0.01)]
    pub dt: f64,
    /// Where to write the dataset (JSON; a summary goes to stdout).
    #[arg(long)]
    pub out: PathBuf,
    /// Physical parameters, e.g. m1=10,l2=0.8 (others keep their defaults).
    #[arg(long)]
    pub set: Option<String>,
    /// q ~ U(−r, r).
    #[arg(long, default_value_t = std::f64::consts::PI)]
    pub q_range: f64,
    /// q̇ ~ U(−r, r).
    #[arg(long, default_value_t = 10.0)]
    pub qdot_range: f64,
    /// u ~ N(0, σ²): one σ for every input, or one per input (e.g. 8,8,3,0.2).
    #[arg(long, default_value = "120", allow_hyphen_values = true)]
    pub u_std: String,
}

pub(super) fn simulate(a: SimulateArgs) -> Result<()> {
    let t = super::template_arg(&a.template)?;
    let params = parse_assignments(&t, a.set.as_deref(), "set")?;
    let stds = a
        .u_std
        .split(',')
        .map(|v| {
            v.trim().parse::<f64>().map_err(|_| {
                Error::invalid(
                    "u-std",
                    format!("'{v}' is not a number (σ, or σ₁,σ₂,… per input)"),
                )
            })
        })
        .collect::<Result<Vec<f64>>>()?;
    let cfg = SimConfig {
        count: a.count,
        seed: a.seed,
        dt: a.dt,
        q_range: a.q_range,
        qdot_range: a.qdot_range,
        u_std: stds.first().copied().unwrap_or(f64::NAN),
        u_stds: if stds.len() > 1 { stds } else { vec![] },
    };
    // The stiffness check asks whether RK4 at the true system's own step is stable.
    let true_dt = match a.trajectories {
        Some(_) => a.dt / a.substeps.max(1) as f64,
        None => a.dt,
    };
    let ds = match a.trajectories {
        None => sim::simulate(&t, params.clone(), &cfg)?,
        Some(count) => {
            let shape = sim::TrajectoryShape {
                count,
                steps: a.steps,
                hold: a.hold,
                substeps: a.substeps,
            };
            sim::simulate_trajectories(&t, params.clone(), &cfg, shape)?
        }
    };
    // After the data: the check looks at its first states too.
    let warnings: Vec<_> = sim::stiffness_warning(
        &t,
        &params,
        true_dt,
        Integrator::Rk4,
        &sim::configurations(&ds, 8),
    )
    .into_iter()
    .collect();
    for w in &warnings {
        eprintln!("warning: {}", w.message);
    }
    write_atomic(&a.out, ds.to_json().as_bytes())?;
    let mut out = json!({"out": a.out, "system": t.name(), "count": ds.count(), "nq": ds.nq, "nv": ds.nv, "n": ds.nv, "m": ds.m, "dt": ds.dt});
    if let Some(k) = a.trajectories {
        out["trajectories"] = json!(k);
        out["substeps"] = json!(a.substeps);
    }
    if !warnings.is_empty() {
        out["warnings"] = json!(warnings);
    }
    super::say(&out)?;
    Ok(())
}

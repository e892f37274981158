//! Simulated trajectories of the true system, for multi-step training, rollout error against
//! horizon and the dashboard's replay: each from a random state, its inputs drawn afresh every
//! few steps and held in between (as a controller's commands are), integrated by RK4, at the
//! recording step or (`substeps`) at a finer one, as a system evolving continuously is
//! recorded by a sensor sampling every Δt.

use super::{SimConfig, TemplateSystem, sample_q, true_step};
use crate::data::Dataset;
use crate::error::{Error, Result};
use crate::physics::integrator::Integrator;
use crate::physics::templates::Template;
use crate::rng::Rng;

/// How many trajectories, of how many transitions, with each input held for how many steps,
/// each step of Δt made of how many RK4 steps of Δt / substeps (1: RK4 at Δt itself).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrajectoryShape {
    pub count: usize,
    pub steps: usize,
    pub hold: usize,
    pub substeps: usize,
}

/// The most RK4 steps one recorded step may be made of.
pub const MAX_SUBSTEPS: usize = 10_000;

/// The most transitions one call simulates (a few seconds of CPU, ~100 MB of JSON written).
pub const MAX_TRANSITIONS: usize = 10_000_000;

/// `shape.count` trajectories of `shape.steps` transitions each: x₀ with q ~ U(−r_q, r_q) and
/// q̇ ~ U(−r_q̇, r_q̇), an input u ~ N(0, σ²) drawn every `shape.hold` steps and held in
/// between, recorded every `cfg.dt` of RK4 at `cfg.dt / shape.substeps` (`cfg.count` is not
/// used). The dataset keeps the trajectories' boundaries.
pub fn simulate_trajectories(
    template: &Template,
    params: Vec<f64>,
    cfg: &SimConfig,
    shape: TrajectoryShape,
) -> Result<Dataset> {
    for (name, v) in [
        ("trajectories", shape.count),
        ("steps", shape.steps),
        ("hold", shape.hold),
        ("substeps", shape.substeps),
    ] {
        if v == 0 {
            return Err(Error::invalid(name, "must be at least 1"));
        }
    }
    if shape.substeps > MAX_SUBSTEPS {
        return Err(Error::invalid(
            "substeps",
            format!("must be at most {MAX_SUBSTEPS}"),
        ));
    }
    let transitions = shape.count.saturating_mul(shape.steps);
    if transitions > MAX_TRANSITIONS {
        return Err(Error::invalid(
            "trajectories",
            format!("trajectories × steps must be at most {MAX_TRANSITIONS}"),
        ));
    }
    // The work is the RK4 steps: ten times the transitions' bound, a minute or so.
    if transitions.saturating_mul(shape.substeps) > 10 * MAX_TRANSITIONS {
        return Err(Error::invalid(
            "substeps",
            format!(
                "trajectories × steps × substeps must be at most {}",
                10 * MAX_TRANSITIONS
            ),
        ));
    }
    cfg.check(template.m())?;
    let (space, m) = (template.space(), template.m());
    let (nq, nv) = (space.nq(), space.nv());
    let sys = TemplateSystem::new(template.clone(), params);
    let mut rng = Rng::derive(cfg.seed, 0x0707_0001);
    let mut arrays: [Vec<f64>; 5] = Default::default();
    for _ in 0..shape.count {
        let q0 = sample_q(&space, &mut rng, cfg.q_range);
        let qd0 = (0..nv).map(|_| rng.uniform_in(-cfg.qdot_range, cfg.qdot_range));
        let mut x: Vec<f64> = q0.into_iter().chain(qd0).collect();
        let mut u = Vec::with_capacity(shape.steps * m);
        for k in 0..shape.steps {
            if k % shape.hold == 0 {
                u.extend(cfg.input(&mut rng, m));
            } else {
                u.extend_from_within(u.len() - m..);
            }
        }
        // Δt / 1 is Δt exactly: one substep is RK4 at Δt, bit for bit.
        let h = cfg.dt / shape.substeps as f64;
        for uk in u.chunks(m) {
            let mut next = true_step(&sys, &x, uk, h, Integrator::Rk4);
            for _ in 1..shape.substeps {
                next = true_step(&sys, &next, uk, h, Integrator::Rk4);
            }
            arrays[0].extend(&x[..nq]);
            arrays[1].extend(&x[nq..]);
            arrays[2].extend(uk);
            arrays[3].extend(&next[..nq]);
            arrays[4].extend(&next[nq..]);
            x = next;
        }
    }
    Dataset::new(cfg.dt, (nq, nv), m, arrays)?.with_trajectories(vec![shape.steps; shape.count])
}

/// `count` trajectories of `steps` transitions of the double pendulum at its default values
/// as the rollout and multi-step experiments draw them: q₀ ~ U(−π, π), q̇₀ ~ U(−2, 2),
/// inputs N(0, 30²) held 0.1 s (10 steps), recorded every 0.01 s of RK4 at 0.01 s.
pub fn double_pendulum_trajectories(count: usize, steps: usize, seed: u64) -> Result<Dataset> {
    double_pendulum_recorded(count, steps, seed, Recording::default())
}

/// How the true system is recorded: every `dt` seconds, from RK4 at `dt / substeps`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recording {
    pub dt: f64,
    pub substeps: usize,
}

impl Default for Recording {
    fn default() -> Self {
        Self {
            dt: SimConfig::default().dt,
            substeps: 1,
        }
    }
}

/// [`double_pendulum_trajectories`] recorded as `rec` says; the inputs are still held 0.1 s
/// (at least one step).
pub fn double_pendulum_recorded(
    count: usize,
    steps: usize,
    seed: u64,
    rec: Recording,
) -> Result<Dataset> {
    let t = Template::DoublePendulum;
    let cfg = SimConfig {
        seed,
        dt: rec.dt,
        qdot_range: 2.0,
        u_std: 30.0,
        ..SimConfig::default()
    };
    let shape = TrajectoryShape {
        count,
        steps,
        hold: ((0.1 / rec.dt).round() as usize).max(1),
        substeps: rec.substeps,
    };
    simulate_trajectories(&t, t.defaults(), &cfg, shape)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trajectories_chain_hold_their_inputs_and_keep_their_boundaries() {
        let d = double_pendulum_trajectories(3, 25, 0).unwrap();
        assert_eq!(d.count(), 75);
        assert_eq!(d.trajectories, Some(vec![25; 3]));
        // Inside a trajectory each row starts where the last one ended, bit for bit: its
        // chains are the trajectories themselves.
        let chains: Vec<usize> = crate::data::trajectories::chains(&d)
            .iter()
            .map(|s| s.length)
            .collect();
        assert_eq!(chains, [25, 25, 25]);
        // Inputs change only every 10 steps: rows 0-9 share one, row 10 has another.
        let u = |r: usize| &d.u[2 * r..2 * r + 2];
        assert!((1..10).all(|r| u(r) == u(0)));
        assert_ne!(u(10), u(9));
        assert_ne!(u(25), u(24), "a new trajectory draws a new input");
        // Starting velocities within ±2.
        assert!(d.qdot[..2].iter().all(|v| v.abs() <= 2.0));
        let t = Template::DoublePendulum;
        let none = TrajectoryShape {
            count: 1,
            steps: 5,
            hold: 0,
            substeps: 1,
        };
        let e = simulate_trajectories(&t, t.defaults(), &SimConfig::default(), none).unwrap_err();
        assert!(e.to_string().contains("hold"), "{e}");
    }
}

//! Particle rollouts (TS∞, Chua et al. 2018): P particles start at x0 and particle p follows
//! member p mod K for the whole rollout, under the inputs (or a policy applied to its own
//! state). What a caller sees is each step's mean over the particles and their spread. A
//! single model's particles all follow it, with zero spread.
//!
//! One computation for every caller: the service streams it in pieces ([`advance`] from the
//! particles' states where the last piece left them, its deadline checked between pieces),
//! an in-process caller takes a whole rollout ([`particle_rollout`]).

use super::Evaluator;
use crate::error::{Error, Result};
use crate::model::report::Spread;

/// The most particles one rollout may propagate: the service's limit and the in-process
/// callers' alike, so a call one refuses the other refuses too.
pub const MAX_PARTICLES: usize = 1024;

/// `count` particles, or the error that names the argument.
pub fn check_particles(count: usize) -> Result<()> {
    if (1..=MAX_PARTICLES).contains(&count) {
        return Ok(());
    }
    Err(Error::invalid(
        "particles",
        format!(
            "must be between 1 and {MAX_PARTICLES} (leave it unset for one rollout of the mean dynamics)"
        ),
    ))
}

/// The error of a rollout whose state left the finite numbers at `step` (the state after
/// `step` inputs; x0 is step 0).
pub fn diverged(step: usize) -> Error {
    Error::invalid(
        "x0",
        format!(
            "the state became non-finite at step {step}: the trajectory left what the model can evaluate"
        ),
    )
}

/// What a particle rollout answers, step after step, row-major.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParticleTrack {
    /// The particles' mean state `[S, 2n]`, one row per state recorded.
    pub mean: Vec<f64>,
    /// Their sample standard deviation per coordinate `[S, 2n]` (`Spread::of`: divided by
    /// P − 1, 0 for one particle).
    pub std: Vec<f64>,
    /// The mean over the particles of the input applied at each step `[T, m]`.
    pub u: Vec<f64>,
    /// Per step, the largest |z| over the particles of the (state, input) the input was
    /// applied at (`Evaluator::max_abs_z`) `[T]`.
    pub max_abs_z: Vec<f64>,
}

impl ParticleTrack {
    /// Appends the mean and spread of the particles' states `[P, nq + nv]` as a row.
    pub fn push_states(&mut self, states: &[f64], nx: usize) {
        for j in 0..nx {
            let column: Vec<f64> = states.iter().skip(j).step_by(nx).copied().collect();
            let s = Spread::of(&column);
            self.mean.push(s.mean);
            self.std.push(s.std);
        }
    }
}

/// A whole rollout of `count` particles from `x0` [2n] over `steps` steps of `dt` seconds, particle p on
/// member p mod K, under `u_t = input(t, x)` for each particle's own state x (a sequence of
/// inputs ignores x; a TVLQR policy, `control::policy::Policy::input`, applies to it): x0's
/// row, then every step's. `stop` is asked before each step (`Error::Cancelled`); a particle
/// whose state is no longer finite ends it with [`diverged`], naming the step.
pub fn particle_rollout(
    eval: &Evaluator,
    x0: &[f64],
    count: usize,
    (steps, dt): (usize, f64),
    input: impl Fn(usize, &[f64]) -> Vec<f64>,
    stop: &dyn Fn() -> bool,
) -> Result<ParticleTrack> {
    check_particles(count)?;
    let nx = eval.config.nx();
    if x0.len() != nx || x0.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid("x0", format!("must be {nx} finite values")));
    }
    let mut states = x0.repeat(count);
    let mut track = ParticleTrack::default();
    track.push_states(&states, nx);
    advance(eval, &mut states, 0, (steps, dt), input, &mut track, stop)?;
    Ok(track)
}

/// `steps` steps of `dt` seconds of every particle from their states `[P, nq + nv]` at step `t` (`input` is asked
/// for steps t, t + 1, …), each step's answer appended to `track` and the states left where
/// the last step took them. On an error (`stop`, or [`diverged`] naming the step) the track
/// and the states hold the steps before it.
pub fn advance(
    eval: &Evaluator,
    states: &mut Vec<f64>,
    t: usize,
    (steps, dt): (usize, f64),
    input: impl Fn(usize, &[f64]) -> Vec<f64>,
    track: &mut ParticleTrack,
    stop: &dyn Fn() -> bool,
) -> Result<()> {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    for s in 0..steps {
        if stop() {
            return Err(Error::Cancelled);
        }
        let us: Vec<f64> = states.chunks(nx).flat_map(|x| input(t + s, x)).collect();
        let next = step(eval, states, &us, dt);
        if next.iter().any(|v| !v.is_finite()) {
            return Err(diverged(t + s + 1));
        }
        let zs = eval.max_abs_z(states, &us);
        track.max_abs_z.push(zs.into_iter().fold(0.0, f64::max));
        track.u.extend(column_means(&us, m));
        track.push_states(&next, nx);
        *states = next;
    }
    Ok(())
}

/// One step of every particle: those of one member as one batch on that member.
fn step(eval: &Evaluator, xs: &[f64], us: &[f64], dt: f64) -> Vec<f64> {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    let (p, k) = (xs.len() / nx, eval.member_count());
    let mut next = vec![0.0; xs.len()];
    for member in 0..k.min(p) {
        let rows: Vec<usize> = (member..p).step_by(k).collect();
        let x: Vec<f64> = rows
            .iter()
            .flat_map(|&r| &xs[r * nx..(r + 1) * nx])
            .copied()
            .collect();
        let u: Vec<f64> = rows
            .iter()
            .flat_map(|&r| &us[r * m..(r + 1) * m])
            .copied()
            .collect();
        let one = eval
            .member(member)
            .predict_until(&x, &u, dt, false, &|| false);
        let (y, _) = one.expect("never stopped");
        for (&r, y) in rows.iter().zip(y.chunks(nx)) {
            next[r * nx..(r + 1) * nx].copy_from_slice(y);
        }
    }
    next
}

/// Each column's mean over the rows of a `[P, w]` array.
fn column_means(a: &[f64], w: usize) -> Vec<f64> {
    (0..w)
        .map(|j| Spread::of(&a.iter().skip(j).step_by(w).copied().collect::<Vec<_>>()).mean)
        .collect()
}

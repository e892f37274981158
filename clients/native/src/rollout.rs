//! Rollouts: one of the mean dynamics, or an ensemble's particles (the core's
//! `particle_rollout`, which the service streams in pieces), answered whole and in the
//! order the gRPC client returns them.

use pyo3::prelude::*;

use crate::convert::{ArrayIn, OrPy, array, rows};
use crate::guard::{Interrupt, admit};
use crate::plan::{Inputs, rollout_inputs};
use graybox_core::error::Error;
use graybox_core::infer::Evaluator;
use graybox_core::infer::particles::{ParticleTrack, check_particles, diverged, particle_rollout};

/// What a rollout call asks for besides its states.
pub struct Want {
    pub with_inputs: bool,
    pub return_z: bool,
    /// None: one rollout of the mean dynamics.
    pub particles: Option<i128>,
    /// Seconds between states (None: the model's own).
    pub dt: Option<f64>,
}

/// A whole rollout: states [T+1, 2n] (the particles' mean), then as asked their spread
/// [T+1, 2n], the applied inputs [T, m] (the particles' mean) and max |z| per step [T].
pub fn rollout<'py>(
    py: Python<'py>,
    eval: &Evaluator,
    x0: ArrayIn<'py>,
    u: Option<ArrayIn<'py>>,
    policy: Option<(ArrayIn<'py>, ArrayIn<'py>, ArrayIn<'py>)>,
    want: Want,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    // The service checks the count first: a bad count is named before any other argument.
    let particles = want
        .particles
        .map(|p| {
            // Out of usize's range is out of 1..=MAX_PARTICLES too: the core names it alike.
            let p = usize::try_from(p).unwrap_or(0);
            check_particles(p).map(|()| p)
        })
        .transpose()
        .or_py(py)?;
    let dt = eval.step_seconds(want.dt).or_py(py)?;
    let x0 = rows("x0", Some(&x0), nx).or_py(py)?;
    if !x0.single {
        return Err(Error::invalid("x0", "is one state [nq + nv], not a batch")).or_py(py);
    }
    let (steps, input) =
        rollout_inputs(u.as_ref(), policy.as_ref(), &eval.config.space, m).or_py(py)?;
    let cost = match particles {
        Some(p) => eval.particle_rollout_cost(steps, p, policy.is_some()),
        None => eval.rollout_cost(steps, policy.is_some()),
    };
    admit(py, &cost)?;
    let interrupt = Interrupt::new();
    let stop = || interrupt.stop();
    let out = py.detach(|| match particles {
        Some(p) => particle_rollout(eval, &x0.data, p, (steps, dt), |t, x| input(t, x), &stop)
            .map(|t| Some(Track::from(t))),
        None => mean_rollout(eval, &x0.data, (steps, dt), &input, &stop),
    });
    let track = interrupt.answer(py, out)?;
    let mut items = vec![array(py, track.x, &[steps + 1, nx])?];
    if let Some(std) = track.std {
        items.push(array(py, std, &[steps + 1, nx])?);
    }
    if want.with_inputs {
        items.push(array(py, track.u, &[steps, m])?);
    }
    if want.return_z {
        items.push(array(py, track.z, &[steps])?);
    }
    Ok(items)
}

/// A rollout's answer: states, their spread (particles only), applied inputs and z.
struct Track {
    x: Vec<f64>,
    std: Option<Vec<f64>>,
    u: Vec<f64>,
    z: Vec<f64>,
}

impl From<ParticleTrack> for Track {
    fn from(t: ParticleTrack) -> Self {
        Self {
            x: t.mean,
            std: Some(t.std),
            u: t.u,
            z: t.max_abs_z,
        }
    }
}

/// The mean dynamics from x0; `None` when stopped.
fn mean_rollout(
    eval: &Evaluator,
    x0: &[f64],
    (steps, dt): (usize, f64),
    input: &Inputs,
    stop: &dyn Fn() -> bool,
) -> Result<Option<Track>, Error> {
    let (nx, m) = (eval.config.nx(), eval.config.m);
    let (mut xs, mut us) = (x0.to_vec(), Vec::with_capacity(steps * m));
    let (mut stopped, mut left, mut done) = (false, None, 0);
    eval.rollout(
        x0,
        (steps, dt),
        |t, x| input(t, x),
        |x, u| {
            if x.iter().any(|v| !v.is_finite()) {
                // The service's error, naming the step whose state left the finite numbers.
                left = Some(diverged(done + 1));
                return false;
            }
            done += 1;
            xs.extend_from_slice(x);
            us.extend_from_slice(u);
            stopped = stop();
            !stopped
        },
    );
    if let Some(e) = left {
        return Err(e);
    }
    if stopped {
        return Ok(None);
    }
    // The service's z of each input: with the state it was applied at, x_t for u_t.
    let z = eval.max_abs_z(&xs[..steps * nx], &us);
    Ok(Some(Track {
        x: xs,
        std: None,
        u: us,
        z,
    }))
}

//! Predict, linearize and rollout, each computed once for all its entry points (plain,
//! `_cancellable`, `_z`, `_z_cancellable` and `_ws`): `z` is None for the calls that do not
//! write it and the caller's pointer otherwise (null is refused like any other output, except
//! by the `_ws` calls, where null means no z); `ws` is the caller's workspace, or null for
//! the calling thread's own.

use graybox_core::error::Error;
use graybox_core::infer::{Workspace, finite_rows, with_workspace};

use crate::boundary::{Cancel, batch_of, guard, input, output, values};
use crate::{GbxModel, GbxStatus, GbxWorkspace, model_ref};

/// The `_z` calls' buffer of `len` values, checked before anything is computed.
///
/// # Safety
/// A non-null pointer in `z` points to `len` writable values, as `output`'s.
unsafe fn z_out<'a>(z: Option<*mut f64>, len: usize) -> Result<Option<&'a mut [f64]>, Error> {
    // SAFETY: the caller's promise, passed on.
    z.map(|p| unsafe { output(p, len, "z") }).transpose()
}

/// Where and how a call computes: in the caller's workspace (null: the calling thread's own)
/// with steps of `dt` seconds (None: the model's own).
pub(crate) struct At {
    pub ws: *mut GbxWorkspace,
    pub dt: Option<f64>,
}

impl At {
    /// The calling thread's workspace and the model's step: every call before the `_ws` ones.
    pub const OWN: At = At {
        ws: std::ptr::null_mut(),
        dt: None,
    };

    pub fn ws(ws: *mut GbxWorkspace) -> At {
        At { ws, dt: None }
    }
}

/// `f` with the caller's workspace, or this thread's own when `ws` is null.
///
/// # Safety
/// A non-null `ws` is a workspace `gbx_workspace_new` gave, used by no other call meanwhile.
unsafe fn with_ws<R>(ws: *mut GbxWorkspace, f: impl FnOnce(&mut Workspace) -> R) -> R {
    // SAFETY: the caller's promise: exclusive for the call.
    match unsafe { ws.as_mut() } {
        Some(ws) => f(&mut ws.0),
        None => with_workspace(f),
    }
}

/// # Safety
/// As `gbx_predict_ws` (with `z` None: `gbx_predict_cancellable` with a workspace).
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn predict(
    model: *const GbxModel,
    at: At,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        let dt = m.eval.step_seconds(at.dt)?;
        let (nx, b) = (m.nq + m.nv, batch_of(batch)?);
        let lx = values("x", b, nx)?;
        values("u", b, m.m)?;
        // SAFETY (all seven): the caller promises these sizes, the flag and the workspace.
        let (x, u) = unsafe { (input(x, b, nx, "x")?, input(u, b, m.m, "u")?) };
        let out = unsafe { output(x_next, lx, "x_next")? };
        let acc = (!accel.is_null()).then(|| unsafe { output(accel, b * m.nv, "accel") });
        let acc = acc.transpose()?;
        let z = unsafe { z_out(z, b)? };
        let cancel = unsafe { Cancel::new(cancel) };
        let done = unsafe {
            with_ws(at.ws, |ws| {
                m.eval
                    .predict_into(ws, x, u, dt, out, acc, &|| cancel.set())
            })
        };
        done.ok_or(Error::Cancelled)?;
        finite_rows("x", "next state", out, nx)?;
        if let Some(z) = z {
            m.eval.max_abs_z_into(x, u, z);
        }
        Ok(())
    })
}

/// # Safety
/// As `gbx_linearize_ws` (with `z` None: `gbx_linearize_cancellable` with a workspace).
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn linearize(
    model: *const GbxModel,
    at: At,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        let (nx, ndx, k) = (m.nq + m.nv, 2 * m.nv, batch_of(batch)?);
        values("x", k, nx)?;
        values("u", k, m.m)?;
        let (la, lb) = (values("a", k, ndx * ndx)?, values("b", k, ndx * m.m)?);
        // SAFETY (all seven): the caller promises these sizes, the flag and the workspace.
        let (x, u) = unsafe { (input(x, k, nx, "x")?, input(u, k, m.m, "u")?) };
        let ja = unsafe { output(a, la, "a")? };
        let jb = match m.m {
            0 => &mut [][..],
            _ => unsafe { output(b, lb, "b")? },
        };
        let z = unsafe { z_out(z, k)? };
        let cancel = unsafe { Cancel::new(cancel) };
        let stop = || cancel.set();
        let done = unsafe { with_ws(at.ws, |ws| m.eval.linearize_into(ws, x, u, ja, jb, &stop)) };
        done.ok_or(Error::Cancelled)?;
        finite_rows("x", "Jacobian", ja, ndx * ndx)?;
        finite_rows("x", "Jacobian", jb, ndx * m.m)?;
        if let Some(z) = z {
            m.eval.max_abs_z_into(x, u, z);
        }
        Ok(())
    })
}

/// # Safety
/// As `gbx_rollout_ws` (with `z` None: `gbx_rollout_cancellable` with a workspace).
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn rollout(
    model: *const GbxModel,
    at: At,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        let dt = m.eval.step_seconds(at.dt)?;
        let nx = m.nq + m.nv;
        values("u", steps, m.m)?;
        let lxs = values("xs", steps.saturating_add(1), nx)?;
        // SAFETY (all six): the caller promises these sizes, the flag and the workspace.
        let (x0, u) = unsafe { (input(x0, 1, nx, "x0")?, input(u, steps, m.m, "u")?) };
        let xs = unsafe { output(xs, lxs, "xs")? };
        let z = unsafe { z_out(z, steps)? };
        let cancel = unsafe { Cancel::new(cancel) };
        let t = unsafe {
            with_ws(at.ws, |ws| {
                m.eval.rollout_into(ws, x0, u, dt, xs, &|| cancel.set())
            })
        };
        // z of (x_t, u_t) for every step taken, as the service's Rollout answers it: a
        // cancelled call's so far, like its states.
        if let Some(z) = z {
            m.eval
                .max_abs_z_into(&xs[..t * nx], &u[..t * m.m], &mut z[..t]);
        }
        if t < steps {
            return Err(Error::Cancelled);
        }
        finite_rows("x0", "state", xs, nx)
    })
}

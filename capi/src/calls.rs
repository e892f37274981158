//! Predict, linearize and rollout, each computed once for its four entry points (plain,
//! `_cancellable`, `_z`, `_z_cancellable`): `z` is None for the calls that do not write it,
//! and the `_z` calls' pointer otherwise (null is refused like any other output).

use graybox_core::error::Error;
use graybox_core::infer::finite_rows;

use crate::boundary::{Cancel, batch_of, guard, input, output, values};
use crate::{GbxModel, GbxStatus, model_ref, pool};

/// The `_z` calls' buffer of `len` values, checked before anything is computed.
///
/// # Safety
/// A non-null pointer in `z` points to `len` writable values, as `output`'s.
unsafe fn z_out<'a>(z: Option<*mut f64>, len: usize) -> Result<Option<&'a mut [f64]>, Error> {
    // SAFETY: the caller's promise, passed on.
    z.map(|p| unsafe { output(p, len, "z") }).transpose()
}

/// # Safety
/// As `gbx_predict_z_cancellable` (with `z` None: `gbx_predict_cancellable`).
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn predict(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        pool::pooled(|| {
            let m = model_ref(model)?;
            let (nx, b) = (2 * m.n, batch_of(batch)?);
            let lx = values("x", b, nx)?;
            values("u", b, m.m)?;
            // SAFETY (all six): the caller promises these sizes and the flag.
            let (x, u) = unsafe { (input(x, b, nx, "x")?, input(u, b, m.m, "u")?) };
            let out = unsafe { output(x_next, lx, "x_next")? };
            let z = unsafe { z_out(z, b)? };
            let cancel = unsafe { Cancel::new(cancel) };
            let (next, acc) = (m.eval)
                .predict_until(x, u, !accel.is_null(), &|| cancel.set())
                .ok_or(Error::Cancelled)?;
            finite_rows("x", "next state", &next, nx)?;
            out.copy_from_slice(&next);
            if let Some(acc) = acc {
                unsafe { output(accel, b * m.n, "accel")? }.copy_from_slice(&acc);
            }
            if let Some(z) = z {
                z.copy_from_slice(&m.eval.max_abs_z(x, u));
            }
            Ok(())
        })
    })
}

/// # Safety
/// As `gbx_linearize_z_cancellable` (with `z` None: `gbx_linearize_cancellable`).
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn linearize(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        pool::pooled(|| {
            let m = model_ref(model)?;
            let (nx, k) = (2 * m.n, batch_of(batch)?);
            values("x", k, nx)?;
            values("u", k, m.m)?;
            values("a", k, nx * nx)?;
            values("b", k, nx * m.m)?;
            // SAFETY (all six): the caller promises these sizes and the flag.
            let (x, u) = unsafe { (input(x, k, nx, "x")?, input(u, k, m.m, "u")?) };
            let z = unsafe { z_out(z, k)? };
            let cancel = unsafe { Cancel::new(cancel) };
            let (ja, jb) = (m.eval)
                .linearize_until(x, u, &|| cancel.set())
                .ok_or(Error::Cancelled)?;
            finite_rows("x", "Jacobian", &ja, nx * nx)?;
            finite_rows("x", "Jacobian", &jb, nx * m.m)?;
            unsafe { output(a, ja.len(), "a")? }.copy_from_slice(&ja);
            if m.m > 0 {
                unsafe { output(b, jb.len(), "b")? }.copy_from_slice(&jb);
            }
            if let Some(z) = z {
                z.copy_from_slice(&m.eval.max_abs_z(x, u));
            }
            Ok(())
        })
    })
}

/// # Safety
/// As `gbx_rollout_z_cancellable` (with `z` None: `gbx_rollout_cancellable`).
pub(crate) unsafe fn rollout(
    model: *const GbxModel,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: Option<*mut f64>,
    cancel: *const i32,
) -> GbxStatus {
    guard(|| {
        pool::pooled(|| {
            let m = model_ref(model)?;
            let nx = 2 * m.n;
            values("u", steps, m.m)?;
            let lxs = values("xs", steps.saturating_add(1), nx)?;
            // SAFETY (all five): the caller promises these sizes and the flag.
            let (x0, u) = unsafe { (input(x0, 1, nx, "x0")?, input(u, steps, m.m, "u")?) };
            let xs = unsafe { output(xs, lxs, "xs")? };
            let z = unsafe { z_out(z, steps)? };
            let cancel = unsafe { Cancel::new(cancel) };
            xs[..nx].copy_from_slice(x0);
            let mut t = 0;
            let input = |t: usize, _: &[f64]| u[t * m.m..(t + 1) * m.m].to_vec();
            m.eval.rollout(x0, steps, input, |x, _| {
                t += 1;
                xs[t * nx..(t + 1) * nx].copy_from_slice(x);
                !cancel.set()
            });
            // z of (x_t, u_t) for every step taken, as the service's Rollout answers it:
            // a cancelled call's so far, like its states.
            if let Some(z) = z {
                z[..t].copy_from_slice(&m.eval.max_abs_z(&xs[..t * nx], &u[..t * m.m]));
            }
            if t < steps {
                return Err(Error::Cancelled);
            }
            finite_rows("x0", "state", xs, nx)
        })
    })
}

//! A workspace the caller owns (as MuJoCo's `mjData` or Pinocchio's `Data`): every piece of
//! per-call scratch, sized once for a model and the largest batch the caller will send, so
//! that the `_ws` calls allocate nothing. One thread uses a workspace at a time; a real-time
//! loop makes one per thread beside its model.

use graybox_core::infer::Workspace;

use crate::boundary::guard;
use crate::calls::At;
use crate::{GbxModel, GbxStatus, calls, model_ref};
use graybox_core::error::Error;

/// Per-call scratch (opaque to C): made for one model, used by one thread at a time.
pub struct GbxWorkspace(pub(crate) Workspace);

/// Makes into `*out` a workspace for `model`'s calls of up to `max_batch` states (and
/// rollouts of any length): it runs each call once on zeros to size its scratch. Used with a
/// larger batch or another model, a workspace grows (taking memory from the system) rather
/// than fail.
///
/// # Safety
/// `model` is a loaded model; `out` points to writable storage for one pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_workspace_new(
    model: *const GbxModel,
    max_batch: usize,
    out: *mut *mut GbxWorkspace,
) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        if out.is_null() {
            return Err(Error::invalid("out", "is a null pointer"));
        }
        if max_batch == 0 {
            return Err(Error::invalid("max_batch", "must be at least 1"));
        }
        let ws = Box::new(GbxWorkspace(Workspace::for_model(&m.eval, max_batch)));
        // SAFETY: `out` is non-null and the caller's to write.
        unsafe { *out = Box::into_raw(ws) };
        Ok(())
    })
}

/// Frees a workspace `gbx_workspace_new` gave (null is ignored). No call may be using it.
///
/// # Safety
/// `ws` is null or a pointer `gbx_workspace_new` gave that has not been freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_workspace_free(ws: *mut GbxWorkspace) {
    if !ws.is_null() {
        // SAFETY: the caller gives back what `Box::into_raw` made, once.
        drop(unsafe { Box::from_raw(ws) });
    }
}

/// `gbx_predict` in the caller's workspace `ws` (null: this thread's own), with every option:
/// `accel` [batch, nv] when not null, `z` [batch] (as `gbx_predict_z`) when not null, and
/// `cancel` (as `gbx_predict_cancellable`) when not null.
///
/// # Safety
/// As `gbx_predict_z_cancellable`; a non-null `ws` came from `gbx_workspace_new` and no other
/// call uses it meanwhile.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn gbx_predict_ws(
    model: *const GbxModel,
    ws: *mut GbxWorkspace,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    let z = (!z.is_null()).then_some(z);
    // SAFETY: the caller's promises.
    unsafe { calls::predict(model, At::ws(ws), x, u, batch, x_next, accel, z, cancel) }
}

/// `gbx_linearize` in the caller's workspace `ws` (null: this thread's own), with `z`
/// [batch] when not null and `cancel` when not null.
///
/// # Safety
/// As `gbx_linearize_z_cancellable`; `ws` as `gbx_predict_ws`'s.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn gbx_linearize_ws(
    model: *const GbxModel,
    ws: *mut GbxWorkspace,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    let z = (!z.is_null()).then_some(z);
    // SAFETY: the caller's promises.
    unsafe { calls::linearize(model, At::ws(ws), x, u, batch, a, b, z, cancel) }
}

/// `gbx_rollout` in the caller's workspace `ws` (null: this thread's own), with `z` [steps]
/// when not null and `cancel` when not null.
///
/// # Safety
/// As `gbx_rollout_z_cancellable`; `ws` as `gbx_predict_ws`'s.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn gbx_rollout_ws(
    model: *const GbxModel,
    ws: *mut GbxWorkspace,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    let z = (!z.is_null()).then_some(z);
    // SAFETY: the caller's promises.
    unsafe { calls::rollout(model, At::ws(ws), x0, u, steps, xs, z, cancel) }
}

/// `gbx_predict_ws` with a step of `dt` seconds instead of the model's own (`gbx_model_dt`):
/// the model's dynamics are continuous, so a model trained on a log at one rate predicts at
/// the rate the caller runs at. `dt` must be in [1e-5, 10] seconds, as a dataset's.
///
/// # Safety
/// As `gbx_predict_ws`.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn gbx_predict_dt_ws(
    model: *const GbxModel,
    ws: *mut GbxWorkspace,
    dt: f64,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    let z = (!z.is_null()).then_some(z);
    let at = At { ws, dt: Some(dt) };
    // SAFETY: the caller's promises.
    unsafe { calls::predict(model, at, x, u, batch, x_next, accel, z, cancel) }
}

/// `gbx_rollout_ws` with steps of `dt` seconds instead of the model's own (as
/// `gbx_predict_dt_ws`).
///
/// # Safety
/// As `gbx_rollout_ws`.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn gbx_rollout_dt_ws(
    model: *const GbxModel,
    ws: *mut GbxWorkspace,
    dt: f64,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    let z = (!z.is_null()).then_some(z);
    let at = At { ws, dt: Some(dt) };
    // SAFETY: the caller's promises.
    unsafe { calls::rollout(model, at, x0, u, steps, xs, z, cancel) }
}

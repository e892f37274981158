//! The calls that also say how far their states and inputs lie from the model's training
//! data: the service's `max_abs_z`, per row the largest |(v − mean) / std| of q, q̇ and u
//! under the statistics the model was trained on. The networks saturate outside the data, so
//! their outputs stay finite but mean little there: above about 4, treat them with doubt.
//! Each is its plain call with one more output, `z`, answered bit for bit as the service
//! answers it.

use crate::calls::At;
use crate::{GbxModel, GbxStatus, calls};

/// `gbx_predict` that also writes `z` [batch]: each row's max_abs_z of (x, u).
///
/// # Safety
/// As `gbx_predict`; `z` points to `batch` writable values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_predict_z(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe {
        calls::predict(
            model,
            At::OWN,
            x,
            u,
            batch,
            x_next,
            accel,
            Some(z),
            std::ptr::null(),
        )
    }
}

/// `gbx_predict_z` that stops when `*cancel` turns nonzero, as `gbx_predict_cancellable`.
///
/// # Safety
/// As `gbx_predict_z`; `cancel` as `gbx_predict_cancellable`'s.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_predict_z_cancellable(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::predict(model, At::OWN, x, u, batch, x_next, accel, Some(z), cancel) }
}

/// `gbx_linearize` that also writes `z` [batch]: each point's max_abs_z of (x, u).
///
/// # Safety
/// As `gbx_linearize`; `z` points to `batch` writable values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_linearize_z(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    z: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe { calls::linearize(model, At::OWN, x, u, batch, a, b, Some(z), std::ptr::null()) }
}

/// `gbx_linearize_z` that stops when `*cancel` turns nonzero, as
/// `gbx_linearize_cancellable`.
///
/// # Safety
/// As `gbx_linearize_z`; `cancel` as `gbx_predict_cancellable`'s.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_linearize_z_cancellable(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::linearize(model, At::OWN, x, u, batch, a, b, Some(z), cancel) }
}

/// `gbx_rollout` that also writes `z` [steps]: for each step t, the max_abs_z of the state
/// x_t and the input u_t applied at it (so z[t] says how far from the data the step that
/// made x_{t+1} was asked to answer).
///
/// # Safety
/// As `gbx_rollout`; `z` points to `steps` writable values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_rollout_z(
    model: *const GbxModel,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe { calls::rollout(model, At::OWN, x0, u, steps, xs, Some(z), std::ptr::null()) }
}

/// `gbx_rollout_z` that stops when `*cancel` turns nonzero (checked at every step),
/// returning `GBX_STATUS_CANCELLED` with the states computed so far in `xs` and their steps'
/// z in `z`; `cancel` as `gbx_predict_cancellable`'s.
///
/// # Safety
/// As `gbx_rollout_z`; `cancel` as `gbx_predict_cancellable`'s.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_rollout_z_cancellable(
    model: *const GbxModel,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    z: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::rollout(model, At::OWN, x0, u, steps, xs, Some(z), cancel) }
}

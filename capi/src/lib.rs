//! graybox's trained models inside a C or C++ controller's own process, with no service in
//! the loop: load a model file (`.gbx`, every format the service loads, ensembles included),
//! then predict, linearize and roll out from the caller's buffers. Built on the inference core
//! alone (`graybox-core`), so the library links no Burn, async runtime, database or RPC
//! framework. The answers are the service's, bit for bit (`tests/answers.rs` replays the
//! service's recorded answers through this ABI).
//!
//! The header `include/graybox.h` is generated from this file by cbindgen
//! (`tests/header.rs` fails when the committed one differs from a fresh generation).
//!
//! Thread safety: a loaded model is immutable; one handle may be used from any number of
//! threads at once. Per-call scratch lives in a workspace, never in the handle: the caller's
//! own (`gbx_workspace_new`, passed to the `_ws` calls: one thread's at a time), or the
//! calling thread's (the other calls). The message of a failed call is kept per thread
//! (`gbx_last_error`).
//!
//! Real-time use: a workspace made for a model and its largest batch holds all the scratch
//! its calls need, so predict, linearize and rollout with it take nothing from the system
//! allocator, by construction (`tests/no_allocation.rs` counts). Calls run on the caller's
//! thread: the library starts no thread.
//!
//! Cancellation: the `_cancellable` variants of predict, linearize and rollout take a flag the
//! caller sets from elsewhere (another thread, a signal handler) to stop a long call, which
//! then returns `GBX_STATUS_CANCELLED`; the plain entry points are those with no flag.
//!
//! How far from the data: the `_z` variants (`z.rs`) also write each row's `max_abs_z`, how
//! far its state and input lie from the training data, as the service answers it.

use std::ffi::{CStr, c_char};
use std::path::Path;

use graybox_core::error::Error;
use graybox_core::infer::Evaluator;
use graybox_core::model::file::ModelFile;

use boundary::guard;
use calls::At;

mod boundary;
mod calls;
mod inverse;
mod workspace;
mod z;

pub use inverse::*;
pub use workspace::*;
pub use z::*;

/// The version of this ABI, as `gbx_abi_version` returns it (and the library's soname,
/// libgraybox_c.so.3). Version 3: states are [q, v] with nq configuration values and nv
/// velocities (`gbx_model_nq`, `gbx_model_nv`), Jacobians 2nv wide in the tangent space.
/// Version 2: caller-owned workspaces (`gbx_workspace_new`, the `_ws` calls), and no
/// allocator of the library's own (version 1 served its calls' memory from per-thread lists
/// it installed process-wide).
pub const GBX_ABI_VERSION: u32 = 3;

/// The ABI version of the loaded library (`GBX_ABI_VERSION` of the header it was built
/// with): a caller compiled against another header should refuse to run.
#[unsafe(no_mangle)]
pub extern "C" fn gbx_abi_version() -> u32 {
    GBX_ABI_VERSION
}

/// What a call returns: `GBX_STATUS_OK`, or why it failed (`gbx_last_error` says more).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GbxStatus {
    Ok = 0,
    /// A null pointer where an array was needed, a zero batch, or an input the model cannot
    /// evaluate (its outputs would not be finite).
    InvalidArgument = 1,
    /// The file is not a graybox model file, or not one this library can read.
    Corrupt = 2,
    /// The file could not be read (the message names it and why).
    Io = 3,
    /// A fault of the library itself (a bug: please report it with the message).
    Internal = 4,
    /// The caller's cancel flag was set: the call stopped before it finished (a rollout's
    /// states so far are in `xs`; other outputs are incomplete).
    Cancelled = 5,
}

/// A loaded model (opaque to C): immutable and shareable across threads.
pub struct GbxModel {
    eval: Evaluator,
    nq: usize,
    nv: usize,
    m: usize,
    dt: f64,
    /// Why the file does not prove it is whole, when it loaded anyway (`gbx_model_warning`).
    warning: Option<std::ffi::CString>,
}

/// The model a file's bytes describe, boxed for C.
fn loaded(file: ModelFile) -> Result<Box<GbxModel>, Error> {
    let eval = Evaluator::from_file(&file)?;
    let c = &file.config;
    let warning = (file.unchecked_warning())
        .map(|w| std::ffi::CString::new(w.message.replace('\0', " ")).unwrap_or_default());
    Ok(Box::new(GbxModel {
        nq: c.nq(),
        nv: c.nv(),
        m: c.m,
        dt: c.dt,
        eval,
        warning,
    }))
}

fn give(model: Result<Box<GbxModel>, Error>, out: *mut *mut GbxModel) -> Result<(), Error> {
    if out.is_null() {
        return Err(Error::invalid("out", "is a null pointer"));
    }
    let model = model?;
    // SAFETY: `out` is non-null and the caller's to write.
    unsafe { *out = Box::into_raw(model) };
    Ok(())
}

/// Loads the model file at `path` (a NUL-terminated UTF-8 path) into `*out`.
///
/// # Safety
/// `path` is a NUL-terminated string; `out` points to writable storage for one pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_load(path: *const c_char, out: *mut *mut GbxModel) -> GbxStatus {
    guard(|| {
        if path.is_null() {
            return Err(Error::invalid("path", "is a null pointer"));
        }
        // SAFETY: the caller promises a NUL-terminated string.
        let path = unsafe { CStr::from_ptr(path) }
            .to_str()
            .map_err(|_| Error::invalid("path", "is not UTF-8"))?;
        let bytes = std::fs::read(Path::new(path))
            .map_err(|e| std::io::Error::new(e.kind(), format!("cannot read {path}: {e}")));
        let file = bytes
            .map_err(Error::Io)
            .and_then(|b| ModelFile::from_bytes(&b));
        give(file.and_then(loaded), out)
    })
}

/// Loads a model file's `len` bytes at `data` (what a `.gbx` file holds) into `*out`.
///
/// # Safety
/// `data` points to `len` readable bytes; `out` to writable storage for one pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_load_buffer(
    data: *const u8,
    len: usize,
    out: *mut *mut GbxModel,
) -> GbxStatus {
    guard(|| {
        if data.is_null() {
            return Err(Error::invalid("data", "is a null pointer"));
        }
        // SAFETY: non-null, and the caller promises `len` bytes.
        let bytes = unsafe { std::slice::from_raw_parts(data, len) };
        give(ModelFile::from_bytes(bytes).and_then(loaded), out)
    })
}

/// Frees a model `gbx_model_load*` gave (null is ignored). No call may be using it.
///
/// # Safety
/// `model` is null or a pointer a load function gave that has not been freed.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_free(model: *mut GbxModel) {
    if !model.is_null() {
        // SAFETY: the caller gives back what `Box::into_raw` made, once.
        drop(unsafe { Box::from_raw(model) });
    }
}

/// The model's configuration values nq: a state is [q, v], nq + nv values.
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_nq(model: *const GbxModel) -> usize {
    // SAFETY: the caller promises a loaded model.
    unsafe { model.as_ref() }.map_or(0, |m| m.nq)
}

/// The model's velocities nv (its degrees of freedom): accelerations are nv values, and
/// Jacobians 2nv × 2nv (A) and 2nv × m (B) in the tangent space.
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_nv(model: *const GbxModel) -> usize {
    // SAFETY: the caller promises a loaded model.
    unsafe { model.as_ref() }.map_or(0, |m| m.nv)
}

/// The model's neutral state into `x` [nq + nv]: every coordinate 0 (a rotation kept as a
/// unit complex number at (1, 0)), at rest; where a loop that knows no state of its own starts.
///
/// # Safety
/// `model` is a loaded model; `x` holds nq + nv values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_neutral(model: *const GbxModel, x: *mut f64) -> GbxStatus {
    guard(|| {
        let m = model_ref(model)?;
        let neutral = m.eval.config.space.origin_state();
        // SAFETY: the caller promises nq + nv values.
        let out = unsafe { boundary::output(x, neutral.len(), "x")? };
        out.copy_from_slice(&neutral);
        Ok(())
    })
}

/// Deprecated: `gbx_model_nv`. The number of coordinates n of a model whose nq = nv = n
/// (a state [q, q̇] of 2n values); for any other model it is nv, and a state is nq + nv.
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_n(model: *const GbxModel) -> usize {
    // SAFETY: the caller promises a loaded model.
    unsafe { gbx_model_nv(model) }
}

/// The model's number of inputs m.
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_m(model: *const GbxModel) -> usize {
    // SAFETY: the caller promises a loaded model.
    unsafe { model.as_ref() }.map_or(0, |m| m.m)
}

/// The model's time step Δt in seconds (one predict is one step of it).
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_dt(model: *const GbxModel) -> f64 {
    // SAFETY: the caller promises a loaded model.
    unsafe { model.as_ref() }.map_or(f64::NAN, |m| m.dt)
}

/// NULL when the model's file proved it is whole (its checksum matched); else why it loaded
/// without that proof (a file written before graybox files carried a checksum), as text the
/// model owns until `gbx_model_free`. A file whose checksum does not match, or whose members
/// disagree with its report, does not load at all: `GBX_STATUS_INVALID_ARGUMENT`, and
/// `gbx_last_error` names `checksum` or `members`.
///
/// # Safety
/// `model` is a loaded model.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_model_warning(model: *const GbxModel) -> *const c_char {
    // SAFETY: the caller promises a loaded model.
    let warning = unsafe { model.as_ref() }.and_then(|m| m.warning.as_ref());
    warning.map_or(std::ptr::null(), |w| w.as_ptr())
}

fn model_ref<'a>(model: *const GbxModel) -> Result<&'a GbxModel, Error> {
    // SAFETY: null or a loaded model, as every entry point's contract says.
    unsafe { model.as_ref() }.ok_or_else(|| Error::invalid("model", "is a null pointer"))
}

/// One step for `batch` states: `x` [batch, nq + nv] (each row q then v) and `u`
/// [batch, m] row-major give `x_next` [batch, nq + nv] and, when `accel` is not null, v̇
/// [batch, nv]. An ensemble answers with its members' mean, as the service does.
///
/// # Safety
/// `model` is a loaded model; the arrays hold the sizes above (`u` may be null when m = 0).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_predict(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe { gbx_predict_cancellable(model, x, u, batch, x_next, accel, std::ptr::null()) }
}

/// `gbx_predict` that stops when `*cancel` turns nonzero (checked between chunks of the
/// batch), returning `GBX_STATUS_CANCELLED`. `cancel` may be NULL (no flag); else another
/// thread or a signal handler sets it while the call runs (a C11 `_Atomic int32_t`, or a
/// `volatile int32_t` stored whole).
///
/// # Safety
/// As `gbx_predict`; a non-null `cancel` points to an aligned `int32_t` that outlives the
/// call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_predict_cancellable(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    x_next: *mut f64,
    accel: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::predict(model, At::OWN, x, u, batch, x_next, accel, None, cancel) }
}

/// The one-step map's Jacobians at `batch` points in the tangent space,
/// x′ ⊖ x̄′ = A (x ⊖ x̄) + B (u − ū): `a` [batch, 2nv, 2nv] and `b` [batch, 2nv, m],
/// row-major (for a model with nq = nv = n, ∂x′/∂x and ∂x′/∂u).
///
/// # Safety
/// `model` is a loaded model; the arrays hold the sizes above (`u` and `b` may be null when
/// m = 0).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_linearize(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe { gbx_linearize_cancellable(model, x, u, batch, a, b, std::ptr::null()) }
}

/// `gbx_linearize` that stops when `*cancel` turns nonzero (checked between chunks of the
/// batch), returning `GBX_STATUS_CANCELLED`; `cancel` as `gbx_predict_cancellable`'s.
///
/// # Safety
/// As `gbx_linearize`; a non-null `cancel` points to an aligned `int32_t` that outlives the
/// call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_linearize_cancellable(
    model: *const GbxModel,
    x: *const f64,
    u: *const f64,
    batch: usize,
    a: *mut f64,
    b: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::linearize(model, At::OWN, x, u, batch, a, b, None, cancel) }
}

/// `steps` steps from `x0` [nq + nv] under the inputs `u` [steps, m]: `xs`
/// [steps + 1, nq + nv] gets x0 and every state after it.
///
/// # Safety
/// `model` is a loaded model; the arrays hold the sizes above (`u` may be null when m = 0).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_rollout(
    model: *const GbxModel,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
) -> GbxStatus {
    // SAFETY: the caller's promises, and no flag.
    unsafe { gbx_rollout_cancellable(model, x0, u, steps, xs, std::ptr::null()) }
}

/// `gbx_rollout` that stops when `*cancel` turns nonzero (checked at every step), returning
/// `GBX_STATUS_CANCELLED` with the states computed so far in `xs`; `cancel` as
/// `gbx_predict_cancellable`'s.
///
/// # Safety
/// As `gbx_rollout`; a non-null `cancel` points to an aligned `int32_t` that outlives the
/// call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn gbx_rollout_cancellable(
    model: *const GbxModel,
    x0: *const f64,
    u: *const f64,
    steps: usize,
    xs: *mut f64,
    cancel: *const i32,
) -> GbxStatus {
    // SAFETY: the caller's promises.
    unsafe { calls::rollout(model, At::OWN, x0, u, steps, xs, None, cancel) }
}

/// The message of this thread's last failed call ("" before any): valid until this thread's
/// next failing call.
#[unsafe(no_mangle)]
pub extern "C" fn gbx_last_error() -> *const c_char {
    boundary::last_error()
}

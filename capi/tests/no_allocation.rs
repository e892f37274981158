//! Real-time use: once a workspace is made for a model and its largest batch, the `_ws` calls
//! (predict with and without q̈, linearize, rollout, each with z, and predict and rollout
//! at a caller's step) take nothing from the
//! system allocator and start no thread, at 1, 8, 32 and 256 states, on the six recorded
//! models. This test binary installs its own counting allocator: the library has none.

use std::ffi::CString;
use std::ptr::{null, null_mut};
use std::sync::Mutex;

use graybox_c::*;

const MODELS: [&str; 6] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/formula-dp-wb",
    "inference/ur5-residual",
    "compat/mvf",
    "compat/wb-x3",
];

#[path = "../../core/tests/counting/mod.rs"]
mod counting;
use counting::allocations;

/// This binary's tests one at a time: the harness runs them on threads of its own, which
/// would start and end inside another test's count of the process's threads.
static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// The process's threads now (Linux: one entry per thread under /proc/self/task).
fn threads() -> usize {
    std::fs::read_dir("/proc/self/task").unwrap().count()
}

struct Loaded {
    model: *mut GbxModel,
    n: usize,
    m: usize,
}

fn load(name: &str) -> Loaded {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures");
    let path = CString::new(format!("{dir}/{name}.gbx")).unwrap();
    let mut model = null_mut();
    // SAFETY: a NUL-terminated path and a place for the pointer.
    let status = unsafe { gbx_model_load(path.as_ptr(), &mut model) };
    assert_eq!(status, GbxStatus::Ok, "{name}");
    // SAFETY: a loaded model.
    let (n, m) = unsafe { (gbx_model_n(model), gbx_model_m(model)) };
    Loaded { model, n, m }
}

/// A call's inputs and outputs for `batch` states, allocated before the count starts.
struct Buffers {
    x: Vec<f64>,
    u: Vec<f64>,
    next: Vec<f64>,
    acc: Vec<f64>,
    a: Vec<f64>,
    b: Vec<f64>,
    z: Vec<f64>,
    us: Vec<f64>,
    xs: Vec<f64>,
}

const STEPS: usize = 5;

fn buffers(l: &Loaded, batch: usize) -> Buffers {
    let nx = 2 * l.n;
    Buffers {
        x: (0..batch * nx)
            .map(|i| 0.1 + 0.05 * (i % 7) as f64)
            .collect(),
        u: (0..batch * l.m)
            .map(|i| 0.2 - 0.1 * (i % 3) as f64)
            .collect(),
        next: vec![0.0; batch * nx],
        acc: vec![0.0; batch * l.n],
        a: vec![0.0; batch * nx * nx],
        b: vec![0.0; batch * nx * l.m],
        z: vec![0.0; batch.max(STEPS)],
        us: vec![0.1; STEPS * l.m],
        xs: vec![0.0; (STEPS + 1) * nx],
    }
}

/// Predict with and without q̈, linearize and a rollout, each with z, in `ws`.
fn calls(l: &Loaded, ws: *mut GbxWorkspace, batch: usize, o: &mut Buffers) {
    let ok = GbxStatus::Ok;
    let u = if l.m == 0 { null() } else { o.u.as_ptr() };
    let us = if l.m == 0 { null() } else { o.us.as_ptr() };
    let (x, z) = (o.x.as_ptr(), o.z.as_mut_ptr());
    // SAFETY: the buffers have the sizes the header documents; no cancel flag.
    unsafe {
        let (next, acc) = (o.next.as_mut_ptr(), o.acc.as_mut_ptr());
        let s = gbx_predict_ws(l.model, ws, x, u, batch, next, acc, z, null());
        assert_eq!(s, ok);
        let s = gbx_predict_ws(l.model, ws, x, u, batch, next, null_mut(), z, null());
        assert_eq!(s, ok);
        let (a, b) = (o.a.as_mut_ptr(), o.b.as_mut_ptr());
        assert_eq!(
            gbx_linearize_ws(l.model, ws, x, u, batch, a, b, z, null()),
            ok
        );
        let xs = o.xs.as_mut_ptr();
        assert_eq!(gbx_rollout_ws(l.model, ws, x, us, STEPS, xs, z, null()), ok);
        // A caller's own step: the same scratch, nothing more.
        let dt = 0.5 * gbx_model_dt(l.model);
        let s = gbx_predict_dt_ws(l.model, ws, dt, x, u, batch, next, acc, z, null());
        assert_eq!(s, ok);
        let s = gbx_rollout_dt_ws(l.model, ws, dt, x, us, STEPS, xs, z, null());
        assert_eq!(s, ok);
    }
}

#[test]
fn with_a_workspace_calls_take_nothing_from_the_system_and_start_no_thread() {
    let _serial = serial();
    for name in MODELS {
        let l = load(name);
        let mut ws = null_mut();
        // The count sees the library's allocations: making the workspace takes its memory.
        // SAFETY: a loaded model and a place for the pointer.
        let made = allocations(|| {
            assert_eq!(
                unsafe { gbx_workspace_new(l.model, 256, &mut ws) },
                GbxStatus::Ok
            )
        });
        assert!(made > 0, "{name}: the allocator counted nothing");
        for batch in [1, 8, 32, 256] {
            let mut o = buffers(&l, batch);
            let before = threads();
            // A thread's start allocates on the starting thread (its handle, its closure), so
            // the count would see one; the live threads are compared as well.
            let made = allocations(|| calls(&l, ws, batch, &mut o));
            assert_eq!(made, 0, "{name}, {batch} states: {made} allocations");
            assert_eq!(
                threads(),
                before,
                "{name}, {batch} states: a thread was left"
            );

            // The calls without a workspace of the caller's (this thread's own) give the same
            // answers bit for bit.
            let mut fresh = buffers(&l, batch);
            calls(&l, null_mut(), batch, &mut fresh);
            for (got, want) in [(&o.next, &fresh.next), (&o.a, &fresh.a), (&o.xs, &fresh.xs)] {
                let bits = |v: &[f64]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(got), bits(want), "{name}, {batch} states");
            }
        }
        // SAFETY: made and loaded above, each freed once.
        unsafe {
            gbx_workspace_free(ws);
            gbx_model_free(l.model);
        }
    }
}

#[test]
fn a_workspace_is_refused_a_zero_batch_and_a_null_model_and_made_for_any_batch() {
    let _serial = serial();
    let l = load("inference/cartpole-wb");
    let mut ws = null_mut();
    // SAFETY: a loaded model (or null, which is refused) and a place for the pointer.
    unsafe {
        assert_eq!(
            gbx_workspace_new(l.model, 0, &mut ws),
            GbxStatus::InvalidArgument
        );
        assert!(ws.is_null());
        assert_eq!(
            gbx_workspace_new(null(), 8, &mut ws),
            GbxStatus::InvalidArgument
        );
        assert_eq!(gbx_abi_version(), GBX_ABI_VERSION);
        // A call's scratch is one unit's: the largest batch there is costs no more.
        assert_eq!(
            gbx_workspace_new(l.model, usize::MAX, &mut ws),
            GbxStatus::Ok
        );
        gbx_workspace_free(ws);
        gbx_model_free(l.model);
    }
}

#[test]
fn workspaces_on_several_threads_give_the_same_answers() {
    let _serial = serial();
    let l = load("inference/ur5-residual");
    let (model, n, m) = (l.model as usize, l.n, l.m);
    let answer = |threads: usize| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                std::thread::spawn(move || {
                    let l = Loaded {
                        model: model as *mut GbxModel,
                        n,
                        m,
                    };
                    let mut ws = null_mut();
                    // SAFETY: a loaded model shared read-only; this thread's workspace.
                    unsafe { gbx_workspace_new(l.model, 8, &mut ws) };
                    let mut o = buffers(&l, 8);
                    calls(&l, ws, 8, &mut o);
                    // SAFETY: made above, freed once.
                    unsafe { gbx_workspace_free(ws) };
                    (o.next, o.a)
                })
            })
            .collect();
        let all: Vec<_> = workers.into_iter().map(|w| w.join().unwrap()).collect();
        all
    };
    let answers = answer(4);
    assert!(answers.windows(2).all(|w| w[0] == w[1]));
    // SAFETY: every thread that used it has ended.
    unsafe { gbx_model_free(l.model) };
}

//! Predict and rollout at a caller's step (`gbx_predict_dt_ws`, `gbx_rollout_dt_ws`): at the
//! model's own Δt the same bits as the `_ws` calls; at another Δt the same bits as the model
//! whose file says that Δt (the model is continuous: only the integrator's step changes); and
//! rollouts of smaller steps converging as RK4's error says.

use std::ffi::CStr;
use std::ptr::{null, null_mut};

use graybox_c::*;

mod common;
use common::{load, path};
use graybox_core::model::file::ModelFile;

const MODELS: [&str; 3] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/ur5-residual",
];

/// The model whose file is `name`'s with Δt = `dt`.
fn load_at(name: &str, dt: f64) -> *mut GbxModel {
    let mut file = ModelFile::load(&path(name)).unwrap();
    file.config.dt = dt;
    let bytes = file.to_bytes().unwrap();
    let mut model = null_mut();
    // SAFETY: the bytes of a model file and a place for the pointer.
    let s = unsafe { gbx_model_load_buffer(bytes.as_ptr(), bytes.len(), &mut model) };
    assert_eq!(s, GbxStatus::Ok);
    model
}

struct Shape {
    nx: usize,
    m: usize,
}

fn shape(model: *const GbxModel) -> Shape {
    // SAFETY: a loaded model.
    unsafe {
        Shape {
            nx: gbx_model_nq(model) + gbx_model_nv(model),
            m: gbx_model_m(model),
        }
    }
}

fn states(s: &Shape, batch: usize) -> (Vec<f64>, Vec<f64>) {
    let x = (0..batch * s.nx).map(|i| 0.1 + 0.04 * (i % 9) as f64);
    let u = (0..batch * s.m).map(|i| 0.3 - 0.2 * (i % 4) as f64);
    (x.collect(), u.collect())
}

/// x' after `dt` (None: the model's own, through `gbx_predict_ws`).
fn predict(model: *const GbxModel, dt: Option<f64>, x: &[f64], u: &[f64]) -> Vec<f64> {
    let mut next = vec![0.0; x.len()];
    let batch = x.len() / shape(model).nx;
    let (xp, up, np) = (x.as_ptr(), u.as_ptr(), next.as_mut_ptr());
    let (ws, none) = (null_mut(), null_mut());
    // SAFETY: buffers of the documented sizes; the thread's own workspace; no flag.
    let s = unsafe {
        match dt {
            None => gbx_predict_ws(model, ws, xp, up, batch, np, none, none, null()),
            Some(dt) => gbx_predict_dt_ws(model, ws, dt, xp, up, batch, np, none, none, null()),
        }
    };
    assert_eq!(s, GbxStatus::Ok);
    next
}

fn bits(a: &[f64]) -> Vec<u64> {
    a.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn a_callers_step_is_the_step_of_the_model_at_that_dt() {
    for name in MODELS {
        let model = load(name);
        // SAFETY: a loaded model.
        let dt = unsafe { gbx_model_dt(model) };
        let (x, u) = states(&shape(model), 5);
        let own = predict(model, None, &x, &u);
        assert_eq!(
            bits(&predict(model, Some(dt), &x, &u)),
            bits(&own),
            "{name}"
        );
        for other in [0.37 * dt, 3.0 * dt] {
            let at = load_at(name, other);
            let want = predict(at, None, &x, &u);
            assert_eq!(
                bits(&predict(model, Some(other), &x, &u)),
                bits(&want),
                "{name}"
            );
            assert_ne!(bits(&want), bits(&own), "{name}: Δt changed nothing");
            // SAFETY: loaded by this test, freed once.
            unsafe { gbx_model_free(at) };
        }
        // SAFETY: as above.
        unsafe { gbx_model_free(model) };
    }
}

/// The state after `k` steps of Δt/`k` from x0 under the held input `u`.
fn rollout(model: *const GbxModel, dt: f64, k: usize, x0: &[f64], u: &[f64]) -> Vec<f64> {
    let nx = x0.len();
    let us = u.repeat(k);
    let mut xs = vec![0.0; (k + 1) * nx];
    let (x, up, xp, h) = (x0.as_ptr(), us.as_ptr(), xs.as_mut_ptr(), dt / k as f64);
    // SAFETY: buffers of the documented sizes; the thread's own workspace; no z or flag.
    let st = unsafe { gbx_rollout_dt_ws(model, null_mut(), h, x, up, k, xp, null_mut(), null()) };
    assert_eq!(st, GbxStatus::Ok);
    xs.split_off(k * nx)
}

#[test]
fn smaller_steps_converge_as_rk4_does() {
    let model = load("inference/cartpole-wb");
    // SAFETY: a loaded model.
    let dt = unsafe { gbx_model_dt(model) };
    let (x0, u) = states(&shape(model), 1);
    let reference = rollout(model, dt, 64, &x0, &u);
    let error = |k: usize| {
        let x = rollout(model, dt, k, &x0, &u);
        (x.iter().zip(&reference))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    // RK4's error over Δt is O(h⁴) in the step h: halving h divides it by about 2⁴ = 16 (8
    // allows for the error's higher-order terms; the 64-step reference's own error is
    // 64⁴ ≈ 1.7·10⁷ times smaller than one step's).
    let (one, two) = (error(1), error(2));
    assert!(one > 0.0 && two < one / 8.0, "{one:e} {two:e}");
    assert_eq!(
        bits(&rollout(model, dt, 1, &x0, &u)),
        bits(&predict(model, None, &x0, &u))
    );
    // SAFETY: loaded by this test, freed once.
    unsafe { gbx_model_free(model) };
}

#[test]
fn a_step_outside_the_range_is_refused_naming_dt() {
    let model = load("inference/dp-mvf");
    let (x, u) = states(&shape(model), 1);
    let mut next = vec![0.0; x.len()];
    for dt in [0.0, -0.01, f64::NAN, f64::INFINITY, 100.0, 1e-7] {
        let (xp, up, np) = (x.as_ptr(), u.as_ptr(), next.as_mut_ptr());
        // SAFETY: buffers of the documented sizes.
        let s = unsafe {
            gbx_predict_dt_ws(
                model,
                null_mut(),
                dt,
                xp,
                up,
                1,
                np,
                null_mut(),
                null_mut(),
                null(),
            )
        };
        assert_eq!(s, GbxStatus::InvalidArgument, "dt = {dt}");
        // SAFETY: the library keeps the message until this thread's next failure.
        let msg = unsafe { CStr::from_ptr(gbx_last_error()) }
            .to_string_lossy()
            .into_owned();
        assert!(msg.starts_with("dt:"), "{msg}");
    }
    // SAFETY: loaded by this test, freed once.
    unsafe { gbx_model_free(model) };
}

//! `gbx_inverse_dynamics`: the core's τ to the bit (the core's own tests check τ against
//! forward dynamics, the closed form and Pinocchio's RNEA), and what it refuses.

use std::ptr::null_mut;

use graybox_c::*;

mod common;
use common::{last_error, load, path};
use graybox_core::infer::Evaluator;
use graybox_core::model::file::ModelFile;

#[test]
fn inverse_dynamics_is_the_cores() {
    for name in [
        "inference/ur5-residual",
        "inference/cartpole-wb",
        "inference/dp-mvf",
    ] {
        let model = load(name);
        let eval = Evaluator::from_file(&ModelFile::load(&path(name)).unwrap()).unwrap();
        let (nx, nv, b) = (eval.config.nx(), eval.config.nv(), 5);
        let x: Vec<f64> = (0..b * nx).map(|i| (0.37 * i as f64).sin()).collect();
        let qdd: Vec<f64> = (0..b * nv).map(|i| 3.0 * (0.91 * i as f64).cos()).collect();
        let want = eval
            .inverse_dynamics_until(&x, &qdd, &|| false)
            .unwrap()
            .unwrap()
            .tau;
        let mut tau = vec![f64::NAN; b * nv];
        // SAFETY: arrays of the sizes the call reads and writes.
        let status =
            unsafe { gbx_inverse_dynamics(model, x.as_ptr(), qdd.as_ptr(), b, tau.as_mut_ptr()) };
        assert_eq!(status, GbxStatus::Ok, "{name}: {}", last_error());
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&tau), bits(&want), "{name}");
        // SAFETY: a null output, which the call refuses before writing.
        let status =
            unsafe { gbx_inverse_dynamics(model, x.as_ptr(), qdd.as_ptr(), b, null_mut()) };
        assert_eq!(status, GbxStatus::InvalidArgument);
        assert!(last_error().contains("tau"), "{}", last_error());
        // SAFETY: a model the test loaded.
        unsafe { gbx_model_free(model) };
    }
}

#[test]
fn a_naive_model_has_no_inverse_dynamics() {
    let model = load("compat/naive");
    let mut tau = [0.0; 8];
    // SAFETY: arrays at least as large as a naive model's call would read and write.
    let status = unsafe {
        gbx_inverse_dynamics(
            model,
            [0.0; 16].as_ptr(),
            [0.0; 8].as_ptr(),
            1,
            tau.as_mut_ptr(),
        )
    };
    assert_eq!(status, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("model"), "{}", last_error());
    // SAFETY: a model the test loaded.
    unsafe { gbx_model_free(model) };
}

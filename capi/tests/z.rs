//! The `_z` calls say how far the model is from its training data: a rollout that drifts away
//! from it (the UR5 left to fall from rest) sees z grow past the README's threshold of doubt,
//! and a rollout's z is its states' and inputs' own, as one predict of them all answers it.
//! Their outputs are those of the plain calls; a null `z` is refused by name, and a cancelled
//! rollout keeps the z of the steps it took.

use std::ptr::{null, null_mut};
use std::sync::atomic::AtomicI32;

use graybox_c::*;

mod common;
use common::{last_error, load};

/// README: "above ~4, treat the outputs with doubt".
const DOUBT: f64 = 4.0;

#[test]
fn a_rollout_that_leaves_the_data_sees_its_z_grow() {
    let model = load("inference/ur5-residual");
    // SAFETY (every call): a loaded model and buffers of the documented sizes.
    let (n, m) = unsafe { (gbx_model_n(model), gbx_model_m(model)) };
    let (nx, steps) = (2 * n, 1000);
    let (x0, u) = (vec![0.0; nx], vec![0.0; steps * m]);
    let (mut xs, mut z) = (vec![0.0; (steps + 1) * nx], vec![f64::NAN; steps]);
    let s = unsafe {
        gbx_rollout_z(
            model,
            x0.as_ptr(),
            u.as_ptr(),
            steps,
            xs.as_mut_ptr(),
            z.as_mut_ptr(),
        )
    };
    assert_eq!(s, GbxStatus::Ok, "{}", last_error());
    // Rest is inside the data; ten seconds of falling under no torque is far outside it.
    assert!(z[0] < DOUBT, "z at rest: {}", z[0]);
    assert!(z[steps - 1] > 5.0 * DOUBT, "z after 10 s: {}", z[steps - 1]);
    let first = z.iter().position(|z| *z > DOUBT).unwrap();
    assert!(
        first > 0 && first < steps - 1,
        "first above {DOUBT} at {first}"
    );
    // Over each tenth of the rollout the largest z grows as the arm falls away.
    let tenths: Vec<f64> = z
        .chunks(steps / 10)
        .map(|c| c.iter().fold(0.0, |a: f64, v| a.max(*v)))
        .collect();
    assert!(tenths.windows(2).all(|w| w[1] > w[0]), "{tenths:?}");

    // The same states as the plain rollout, and z of (x_t, u_t) as predict answers it.
    let mut plain = vec![0.0; xs.len()];
    let s = unsafe { gbx_rollout(model, x0.as_ptr(), u.as_ptr(), steps, plain.as_mut_ptr()) };
    assert_eq!(s, GbxStatus::Ok);
    assert!(
        plain
            .iter()
            .zip(&xs)
            .all(|(a, b)| a.to_bits() == b.to_bits())
    );
    let (mut next, mut each) = (vec![0.0; steps * nx], vec![0.0; steps]);
    let s = unsafe {
        gbx_predict_z(
            model,
            xs.as_ptr(),
            u.as_ptr(),
            steps,
            next.as_mut_ptr(),
            null_mut(),
            each.as_mut_ptr(),
        )
    };
    assert_eq!(s, GbxStatus::Ok, "{}", last_error());
    assert!(each.iter().zip(&z).all(|(a, b)| a.to_bits() == b.to_bits()));
    unsafe { gbx_model_free(model) };
}

#[test]
fn a_null_z_is_refused_and_a_cancelled_rollout_keeps_its_steps_z() {
    let model = load("inference/dp-mvf");
    let (x, u) = ([0.1, 0.2, 0.3, 0.4], [0.5, -0.5]);
    let (mut next, mut a, mut b) = ([0.0; 4], [0.0; 16], [0.0; 8]);
    // SAFETY (every call): a loaded model and buffers of the documented sizes, z aside.
    let s = unsafe {
        gbx_predict_z(
            model,
            x.as_ptr(),
            u.as_ptr(),
            1,
            next.as_mut_ptr(),
            null_mut(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("z:"), "{}", last_error());
    let s = unsafe {
        gbx_linearize_z(
            model,
            x.as_ptr(),
            u.as_ptr(),
            1,
            a.as_mut_ptr(),
            b.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("z:"), "{}", last_error());

    let steps = 50;
    let us = vec![0.5; 2 * steps];
    let mut xs = vec![0.0; 4 * (steps + 1)];
    let s = unsafe {
        gbx_rollout_z(
            model,
            x.as_ptr(),
            us.as_ptr(),
            steps,
            xs.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::InvalidArgument);
    assert!(last_error().starts_with("z:"), "{}", last_error());

    let (mut all, mut cut) = (vec![0.0; steps], vec![f64::NAN; steps]);
    let s = unsafe {
        gbx_rollout_z_cancellable(
            model,
            x.as_ptr(),
            us.as_ptr(),
            steps,
            xs.as_mut_ptr(),
            all.as_mut_ptr(),
            null(),
        )
    };
    assert_eq!(s, GbxStatus::Ok);
    // A flag set before the call: the rollout stops after its first step.
    let set = AtomicI32::new(1);
    let s = unsafe {
        gbx_rollout_z_cancellable(
            model,
            x.as_ptr(),
            us.as_ptr(),
            steps,
            xs.as_mut_ptr(),
            cut.as_mut_ptr(),
            set.as_ptr().cast_const(),
        )
    };
    assert_eq!(s, GbxStatus::Cancelled);
    assert_eq!(cut[0].to_bits(), all[0].to_bits());
    assert!(
        cut[1..].iter().all(|z| z.is_nan()),
        "steps not taken keep what was there"
    );
    unsafe { gbx_model_free(model) };
}

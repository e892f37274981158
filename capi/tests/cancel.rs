//! A C caller's cancel flag stops a long call: `GBX_STATUS_CANCELLED`, distinct from every
//! failure, with the call's work left undone; an unset or absent flag changes no answer.

use std::ptr::{null, null_mut};
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::Duration;

use graybox_c::*;

mod common;
use common::{last_error, load};

/// Distinct states and inputs, `batch` of each (n = 2, m = 2).
fn batch(batch: usize) -> (Vec<f64>, Vec<f64>) {
    let x = (0..4 * batch)
        .map(|i| ((i % 97) as f64 * 0.01).sin())
        .collect();
    let u = (0..2 * batch)
        .map(|i| ((i % 89) as f64 * 0.02).cos())
        .collect();
    (x, u)
}

#[test]
fn a_set_flag_stops_predict_and_linearize_and_an_unset_one_changes_nothing() {
    let model = load("inference/dp-mvf");
    let (x, u) = batch(20_000);
    let (set, unset) = (AtomicI32::new(1), AtomicI32::new(0));
    let (mut plain, mut flagged) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    // SAFETY (every call): a loaded model and buffers of the documented sizes.
    let s = unsafe {
        gbx_predict(
            model,
            x.as_ptr(),
            u.as_ptr(),
            20_000,
            plain.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, GbxStatus::Ok, "{}", last_error());
    for flag in [null(), unset.as_ptr().cast_const()] {
        let s = unsafe {
            gbx_predict_cancellable(
                model,
                x.as_ptr(),
                u.as_ptr(),
                20_000,
                flagged.as_mut_ptr(),
                null_mut(),
                flag,
            )
        };
        assert_eq!(s, GbxStatus::Ok, "{}", last_error());
        assert!(
            plain
                .iter()
                .zip(&flagged)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }
    let mut untouched = vec![f64::NAN; x.len()];
    let s = unsafe {
        gbx_predict_cancellable(
            model,
            x.as_ptr(),
            u.as_ptr(),
            20_000,
            untouched.as_mut_ptr(),
            null_mut(),
            set.as_ptr(),
        )
    };
    assert_eq!(s, GbxStatus::Cancelled, "{}", last_error());
    assert!(last_error().contains("cancel"), "{}", last_error());
    assert!(untouched.iter().all(|v| v.is_nan()));
    let (mut a, mut b) = (vec![0.0; 20_000 * 16], vec![0.0; 20_000 * 8]);
    let s = unsafe {
        gbx_linearize_cancellable(
            model,
            x.as_ptr(),
            u.as_ptr(),
            20_000,
            a.as_mut_ptr(),
            b.as_mut_ptr(),
            set.as_ptr(),
        )
    };
    assert_eq!(s, GbxStatus::Cancelled, "{}", last_error());
    unsafe { gbx_model_free(model) };
}

/// A rollout of a million steps (seconds of work) stops when another thread sets the flag
/// while it runs, with the states after that left unwritten.
#[test]
fn a_flag_set_from_another_thread_stops_a_long_rollout() {
    let model = load("inference/dp-mvf");
    let steps = 1_000_000;
    let u = vec![0.1; 2 * steps];
    let x0 = [0.1, 0.2, 0.0, 0.0];
    let mut xs = vec![f64::NAN; 4 * (steps + 1)];
    let flag = AtomicI32::new(0);
    let status = std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(100));
            flag.store(1, Ordering::Relaxed);
        });
        // SAFETY: a loaded model, buffers of the documented sizes, a flag that outlives the call.
        unsafe {
            gbx_rollout_cancellable(
                model,
                x0.as_ptr(),
                u.as_ptr(),
                steps,
                xs.as_mut_ptr(),
                flag.as_ptr(),
            )
        }
    });
    assert_eq!(status, GbxStatus::Cancelled, "{}", last_error());
    assert!(
        xs[4..8].iter().all(|v| v.is_finite()),
        "the first step was taken"
    );
    assert!(
        xs[4 * steps..].iter().all(|v| v.is_nan()),
        "the last state was never written"
    );
    unsafe { gbx_model_free(model) };
}

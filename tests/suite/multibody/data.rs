//! The `Data` workspace's root-frame algorithms (docs/robots.md#the-data-workspace): CRBA,
//! the bias, forward dynamics and the analytic derivatives of RNEA against the body-frame
//! recursions over jets, on every fixture robot and the mimic robot; and a workspace reused
//! across robots of different sizes answers as a fresh one.

use super::*;
use graybox::physics::multibody::{Data, id_partials};

/// Every fixture model and the mimic robot (joints sharing a coordinate, with offsets).
fn all_models() -> Vec<(&'static str, multibody::Model)> {
    let mut all: Vec<_> = models().collect();
    all.push(("mimic", mimic_robot().multibody([0.0, 0.0, -9.81])));
    all
}

/// ∂ID/∂(q, q̇) from `Data::id_derivatives` equals RNEA over `Jet<64>` (the body-frame
/// recursion, differentiated by forward mode: an independent route to the same partials) at
/// random states, to 1e-10 of max(1, |ref|): both are exact to rounding, ~1e-14 of the terms
/// (≤ 1e3 here); a missing or wrong term (gravity's, a mimic multiplier, a branch) is O(1).
#[test]
fn analytic_rnea_derivatives_equal_forward_mode() {
    let mut rng = Rng::new(56);
    for (name, model) in all_models() {
        let n = model.n;
        for s in 0..4 {
            let [q, qd, qdd] = random_state(&mut rng, n, 1.5);
            let got = id_partials(&model, &q, &qd, &qdd);
            let want = jet_id_partials(&model, &q, &qd, &qdd);
            assert!(
                err(&flat(&got), &flat(&want)) < 1e-10,
                "{name} {s}: {got:?} vs {want:?}"
            );
        }
    }
}

/// The workspace's M (CRBA in the root frame), C q̇ + g and q̈ (by CRBA and Cholesky, and by
/// ABA in the root frame) equal the body-frame CRBA, RNEA and forward dynamics. The root frame sums in another order, so bit-for-bit equality does
/// not hold: the bound is 1e-12 of max(1, |ref|) for M and the bias (rounding ~1e-15 of
/// terms ≤ 1e2) and 1e-9 for q̈ (the same rounding amplified by M's condition, ≤ 1e4 here).
/// The workspace is the same one throughout, resized between robots.
#[test]
fn the_workspace_equals_the_body_frame_recursions() {
    let mut rng = Rng::new(57);
    let mut data = Data::default();
    for round in 0..2 {
        for (name, model) in all_models() {
            let n = model.n;
            let [q, qd, tau] = random_state(&mut rng, n, 1.5);
            data.crba_forward(&model, &q, &qd, &tau);
            let m = crba(&model, &q);
            assert!(err(&data.mass, &flat(&m)) < 1e-12, "{name} {round}: M");
            let b = bias(&model, &q, &qd);
            assert!(err(&data.bias, &b) < 1e-12, "{name} {round}: bias");
            let qdd = forward_dynamics(&model, &q, &qd, &tau);
            assert!(err(&data.qdd, &qdd) < 1e-9, "{name} {round}: q̈ by CRBA");
            data.forward_dynamics(&model, &q, &qd, &tau);
            assert!(err(&data.qdd, &qdd) < 1e-9, "{name} {round}: q̈ by ABA");
            let fresh = Data::new(&model);
            let mut fresh = fresh;
            fresh.fd_partials(&model, &q, &qd, &tau);
            data.fd_partials(&model, &q, &qd, &tau);
            assert_eq!(fresh.id_dq, data.id_dq, "{name} {round}: reused vs fresh");
            assert_eq!(fresh.id_dqd, data.id_dqd, "{name} {round}: reused vs fresh");
        }
    }
}

//! The `Data` workspace's root-frame algorithms (docs/robots.md#the-data-workspace): the
//! analytic derivatives of RNEA against RNEA over dual numbers, ABA against CRBA and Cholesky, on every
//! fixture robot and the mimic robot; and a workspace reused across robots of different sizes
//! answers as a fresh one.

use super::*;
use graybox::physics::multibody::{Data, id_partials};

/// Every fixture model and the mimic robot (joints sharing a coordinate, with offsets).
fn all_models() -> Vec<(&'static str, multibody::Model)> {
    let mut all: Vec<_> = models().collect();
    all.push(("mimic", mimic_robot().multibody([0.0, 0.0, -9.81])));
    all
}

/// ∂ID/∂(q, q̇) from `Data::id_derivatives` equals RNEA over `Jet<64>` (RNEA's passes
/// differentiated by forward mode: an independent route to the same partials) at
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
            let want = dual_id_partials(&model, &q, &qd, &qdd);
            assert!(
                err(&flat(&got), &flat(&want)) < 1e-10,
                "{name} {s}: {got:?} vs {want:?}"
            );
        }
    }
}

/// q̈ by ABA in the root frame equals q̈ by CRBA and Cholesky, two algorithms: to 1e-9 of
/// max(1, |ref|) (their sums run in different orders; rounding ~1e-15 of terms ≤ 1e2,
/// amplified by M's condition, ≤ 1e4 here; a mimic robot takes CRBA both ways). And one
/// workspace reused across robots of different sizes answers bit for bit as a fresh one: M,
/// the bias, q̈ and the partials of RNEA (a value left over from a larger robot would show).
/// M, g and C q̇ themselves are Pinocchio's (`crba_and_rnea_equal_pinocchio`).
#[test]
fn aba_equals_crba_and_a_reused_workspace_a_fresh_one() {
    let mut rng = Rng::new(57);
    let mut data = Data::default();
    for round in 0..2 {
        for (name, model) in all_models() {
            let n = model.n;
            let [q, qd, tau] = random_state(&mut rng, n, 1.5);
            let mut fresh = Data::new(&model);
            data.crba_forward(&model, &q, &qd, &tau);
            fresh.crba_forward(&model, &q, &qd, &tau);
            assert_eq!(fresh.mass, data.mass, "{name} {round}: M, reused vs fresh");
            assert_eq!(
                fresh.bias, data.bias,
                "{name} {round}: bias, reused vs fresh"
            );
            assert_eq!(fresh.qdd, data.qdd, "{name} {round}: q̈, reused vs fresh");
            let by_crba = data.qdd.clone();
            data.forward_dynamics(&model, &q, &qd, &tau);
            assert!(err(&data.qdd, &by_crba) < 1e-9, "{name} {round}: q̈ by ABA");
            fresh.fd_partials(&model, &q, &qd, &tau);
            data.fd_partials(&model, &q, &qd, &tau);
            assert_eq!(fresh.id_dq, data.id_dq, "{name} {round}: reused vs fresh");
            assert_eq!(fresh.id_dqd, data.id_dqd, "{name} {round}: reused vs fresh");
        }
    }
}

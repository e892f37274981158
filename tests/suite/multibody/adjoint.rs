//! The vector–Jacobian product of forward dynamics (`multibody::adjoint`), a training
//! step's backward pass: Yᵀλ without Y equals the regressor's, and every gradient equals
//! central differences of ḡ · FD.

use graybox::physics::multibody::adjoint::{forward_dynamics_adjoint, parameter_gradient};
use graybox::physics::multibody::regressor::{regressor, standard_parameters, with_parameters};
use graybox::physics::multibody::{self, forward_dynamics};
use graybox::rng::Rng;

use super::common::urdf::fixture;
use super::{dual_id_partials, err, gravity, models, random, random_state, with_rotors};

/// Aᵀλ for the rows of A.
fn transposed_times(a: &[Vec<f64>], l: &[f64]) -> Vec<f64> {
    (0..a[0].len())
        .map(|k| a.iter().zip(l).map(|(row, l)| row[k] * l).sum())
        .collect()
}

/// Yᵀλ by the O(n) recursion equals the regressor's columns times λ at random states and λ,
/// to 1e-9 of max(1, |ref|) (the same products summed in another order); with armatures, their
/// columns too, and Y π is τ.
#[test]
fn the_parameter_gradient_is_the_regressor_transposed() {
    let mut rng = Rng::new(29);
    for (name, model) in models() {
        let model = with_rotors(model, &mut rng);
        let n = model.n;
        for s in 0..3 {
            let [q, qd, qdd] = random_state(&mut rng, n, 1.5);
            let l = random(&mut rng, n, 1.0);
            let y = regressor(&model, &q, &qd, &qdd);
            let want = transposed_times(&y, &l);
            let got = parameter_gradient(&model, &q, &qd, &qdd, &l);
            assert!(err(&got, &want) < 1e-9, "{name} {s}: {got:?} vs {want:?}");
            let pi = standard_parameters(&model);
            let y_pi: Vec<f64> = y
                .iter()
                .map(|r| r.iter().zip(&pi).map(|(a, b)| a * b).sum())
                .collect();
            let tau = multibody::inverse_dynamics(&model, &q, &qd, &qdd);
            assert!(
                err(&y_pi, &tau) < 1e-9,
                "{name} {s}: Yπ {y_pi:?} vs τ {tau:?}"
            );
        }
    }
}

/// ∂(ḡ·FD)/∂(q, q̇, τ, π) by the adjoint equal central differences to 1e-6 of max(1, |ref|)
/// (h = 1e-6; for π, 1e-5 of the entry and at least 1e-8: truncation ~h² times FD's third
/// derivative and rounding ~1e-16·|FD|/h both stay below 1e-7 of the gradients here, while a
/// missing term or sign moves them by order 1), on the UR5, the Panda (mimic finger: CRBA
/// and Cholesky) and Solo 12 (branching), each with armatures (π's last n entries).
#[test]
fn the_adjoint_is_central_differences() {
    let mut rng = Rng::new(31);
    for name in ["robots/ur5", "robots/panda", "robots/solo12"] {
        let (tree, fx) = fixture(name);
        let model = with_rotors(tree.multibody(gravity(&fx)), &mut rng);
        let n = model.n;
        let (q, qd, tau, g) = (
            random(&mut rng, n, 1.5),
            random(&mut rng, n, 1.5),
            random(&mut rng, n, 2.0),
            random(&mut rng, n, 1.0),
        );
        let adj = forward_dynamics_adjoint(&model, &q, &qd, &tau, &g);
        let loss = |m: &multibody::Model, q: &[f64], qd: &[f64], tau: &[f64]| -> f64 {
            forward_dynamics(m, q, qd, tau)
                .iter()
                .zip(&g)
                .map(|(a, b)| a * b)
                .sum()
        };
        let h = 1e-6;
        let central = |f: &dyn Fn(f64) -> f64| (f(h) - f(-h)) / (2.0 * h);
        let along = |x: &[f64], k: usize, e: f64| {
            let mut x = x.to_vec();
            x[k] += e;
            x
        };
        let fd_q: Vec<f64> = (0..n)
            .map(|k| central(&|e| loss(&model, &along(&q, k, e), &qd, &tau)))
            .collect();
        let fd_qd: Vec<f64> = (0..n)
            .map(|k| central(&|e| loss(&model, &q, &along(&qd, k, e), &tau)))
            .collect();
        let fd_tau: Vec<f64> = (0..n)
            .map(|k| central(&|e| loss(&model, &q, &qd, &along(&tau, k, e))))
            .collect();
        let pi = standard_parameters(&model);
        // A step relative to each parameter: Solo 12's feet have inertias of 1e-5, which a
        // step of 1e-6 would change by a tenth (FD is far from linear in them).
        let fd_pi: Vec<f64> = (0..pi.len())
            .map(|k| {
                let hk = (1e-5 * pi[k].abs()).max(1e-8);
                let f = |e: f64| loss(&with_parameters(&model, &along(&pi, k, e)), &q, &qd, &tau);
                (f(hk) - f(-hk)) / (2.0 * hk)
            })
            .collect();
        for (what, got, want) in [
            ("q", &adj.q, &fd_q),
            ("q̇", &adj.qd, &fd_qd),
            ("τ", &adj.tau, &fd_tau),
            ("π", &adj.pi, &fd_pi),
        ] {
            assert!(
                err(got, want) < 1e-6,
                "{name} ∂/∂{what}: {got:?} vs {want:?}"
            );
        }
        assert_eq!(adj.qdd, forward_dynamics(&model, &q, &qd, &tau));
    }
}

/// The adjoint's O(n) pass gives λᵀ∂ID/∂(q, q̇) equal to the partials of RNEA over `Jet<64>`
/// (forward mode through the body-frame recursion, an independent route) times λ on every
/// fixture robot (mimic joints, branches, prismatic fingers), to 1e-9 of max(1, |ref|).
#[test]
fn the_reverse_pass_is_the_jets_transposed() {
    use graybox::physics::multibody::adjoint::id_gradient;
    let mut rng = Rng::new(37);
    for (name, model) in models() {
        let n = model.n;
        for s in 0..3 {
            let [q, qd, qdd] = random_state(&mut rng, n, 1.5);
            let l = random(&mut rng, n, 1.0);
            let id = dual_id_partials(&model, &q, &qd, &qdd);
            let want = transposed_times(&id, &l);
            let (dq, dqd) = id_gradient(&model, &q, &qd, &qdd, &l);
            let got = [dq, dqd].concat();
            assert!(err(&got, &want) < 1e-9, "{name} {s}: {got:?} vs {want:?}");
        }
    }
}

/// The torque loss's node (`Data::inverse_adjoint`): ∂(ḡ·ID)/∂(q, q̇, q̈, π) equal central
/// differences of RNEA, to 1e-6 of max(1, |ref|) with the steps and reasons of the forward
/// dynamics' test above (ID is linear in q̈ and π, so there only rounding separates them).
#[test]
fn the_inverse_dynamics_adjoint_is_central_differences() {
    use graybox::physics::multibody::adjoint::inverse_dynamics_adjoint;
    use graybox::physics::multibody::rnea::inverse_dynamics;
    let mut rng = Rng::new(41);
    for name in ["robots/ur5", "robots/panda", "robots/solo12"] {
        let (tree, fx) = fixture(name);
        let model = with_rotors(tree.multibody(gravity(&fx)), &mut rng);
        let n = model.n;
        let [q, qd, qdd] = random_state(&mut rng, n, 1.5);
        let g = random(&mut rng, n, 1.0);
        let got = inverse_dynamics_adjoint(&model, &q, &qd, &qdd, &g);
        let loss = |m: &multibody::Model, x: [&[f64]; 3]| -> f64 {
            let tau = inverse_dynamics(m, x[0], x[1], x[2]);
            tau.iter().zip(&g).map(|(a, b)| a * b).sum()
        };
        let h = 1e-6;
        let along = |x: &[f64], k: usize, e: f64| {
            let mut x = x.to_vec();
            x[k] += e;
            x
        };
        let by = |i: usize| -> Vec<f64> {
            (0..n)
                .map(|k| {
                    let f = |e: f64| {
                        let mut x = [q.clone(), qd.clone(), qdd.clone()];
                        x[i] = along(&x[i], k, e);
                        loss(&model, [&x[0], &x[1], &x[2]])
                    };
                    (f(h) - f(-h)) / (2.0 * h)
                })
                .collect()
        };
        let pi = standard_parameters(&model);
        let fd_pi: Vec<f64> = (0..pi.len())
            .map(|k| {
                let hk = (1e-5 * pi[k].abs()).max(1e-8);
                let f = |e: f64| loss(&with_parameters(&model, &along(&pi, k, e)), [&q, &qd, &qdd]);
                (f(hk) - f(-hk)) / (2.0 * hk)
            })
            .collect();
        let want = [by(0), by(1), by(2), fd_pi];
        for (what, (got, want)) in ["q", "q̇", "q̈", "π"].iter().zip(got.iter().zip(&want)) {
            assert!(
                err(got, want) < 1e-6,
                "{name} ∂/∂{what}: {got:?} vs {want:?}"
            );
        }
    }
}

//! Inverse dynamics inverts forward dynamics on every structured kind of model: at the model's
//! own q̈ for (x, u), τ = M q̈ + c + ∇V − F(q, q̇, 0) is F(q, q̇, u) − F(q, q̇, 0), the force the
//! inputs add (Energy's `applied` at u and at 0). A URDF robot's τ against Pinocchio's RNEA is
//! tests/python/test_energy.py's.

mod recorded;
use recorded::load;

/// (An ensemble's τ is its members' mean at the given q̈, each with its own M, and its q̈ the
/// members' mean: the identity holds member by member, not for the means.)
const MODELS: [&str; 4] = [
    "inference/dp-mvf",
    "inference/cartpole-wb",
    "inference/formula-dp-wb",
    "inference/ur5-residual",
];

#[test]
fn inverse_dynamics_at_the_models_acceleration_is_the_inputs_force() {
    let batch = 9;
    for name in MODELS {
        let eval = load(name);
        let (nx, nv, m) = (eval.config.nx(), eval.config.nv(), eval.config.m);
        let x: Vec<f64> = (0..batch * nx).map(|i| (0.37 * i as f64).sin()).collect();
        let u: Vec<f64> = (0..batch * m)
            .map(|i| 2.0 * (0.91 * i as f64).cos())
            .collect();
        let qdd = eval.predict(&x, &u, true).1.unwrap();
        let inv = eval
            .inverse_dynamics_until(&x, &qdd, &|| false)
            .unwrap()
            .unwrap();
        let forced = eval.energy_until(&x, &u, &|| false).unwrap().unwrap();
        let zero = vec![0.0; u.len()];
        let passive = eval.energy_until(&x, &zero, &|| false).unwrap().unwrap();
        assert_eq!(inv.terms.applied, passive.applied, "{name}: F(q, q̇, 0)");
        // The parts are the passive ones: the input's, zero at u = 0, is not one of them.
        let names: Vec<_> = inv.terms.parts.iter().map(|p| p.name).collect();
        let want: Vec<_> = (passive.parts.iter())
            .map(|p| p.name)
            .filter(|n| *n != "input")
            .collect();
        assert_eq!(names, want, "{name}: parts");
        for i in 0..batch * nv {
            let want = forced.applied[i] - passive.applied[i];
            // q̈ solved from M and multiplied back: rounding of M's condition (≤ 1e4 here) times
            // the largest term, which 1e-9 of the terms' scale leaves room for; a wrong sign or
            // a missing term is of the terms' own size.
            let scale = [&inv.terms.inertial, &inv.terms.coriolis, &inv.terms.gravity]
                .iter()
                .map(|v| v[i].abs())
                .fold(1.0, f64::max);
            assert!(
                (inv.tau[i] - want).abs() <= 1e-9 * scale,
                "{name} [{i}]: τ {} against F(u) − F(0) {want}",
                inv.tau[i]
            );
        }
    }
}

#[test]
fn inverse_dynamics_names_a_wrong_shape() {
    let eval = load("inference/cartpole-wb");
    let nx = eval.config.nx();
    let x = vec![0.1; 2 * nx];
    let e = eval
        .inverse_dynamics_until(&x, &[0.0; 3], &|| false)
        .unwrap_err();
    assert!(e.to_string().starts_with("qdd"), "{e}");
    let e = eval
        .inverse_dynamics_until(&x[1..], &[0.0; 4], &|| false)
        .unwrap_err();
    assert!(e.to_string().starts_with("x"), "{e}");
    let stopped = eval
        .inverse_dynamics_until(&x, &[0.0; 4], &|| true)
        .unwrap();
    assert!(stopped.is_none());
}

//! The multibody algorithms (docs/robots.md#multibody-dynamics): CRBA's M(q),
//! RNEA's g(q) and C(q, q̇)q̇ equal Pinocchio's at every fixture state (the same fixtures as
//! tests/suite/urdf.rs); forward dynamics (ABA, or CRBA + Cholesky with mimic joints) inverts them;
//! they agree with the tests' Jacobian form (`common::jacobian_form`: M = Σ JᵀIJ, V) for other,
//! random physical inertias; their dual-number derivatives are central differences'; a model
//! built by hand (`built.rs`) is the robot the URDF producer builds.

use std::f64::consts::PI;

use graybox::physics::dual::{Dual, Jet};
use graybox::physics::multibody::Inertial;
use graybox::physics::multibody::{
    self, aba, bias, coriolis, crba, crba_forward, fd_over_dual, forward_dynamics,
    forward_dynamics_derivatives, gravity_torques, inverse_dynamics, kinetic_energy,
    potential_energy,
};
use graybox::physics::urdf::Tree;
use graybox::rng::Rng;
use serde_json::Value;

#[path = "multibody/adjoint.rs"]
mod adjoint;
#[path = "multibody/base.rs"]
mod base;
#[path = "multibody/built.rs"]
mod built;
use crate::common;
#[path = "multibody/data.rs"]
mod data;
#[path = "multibody/evaluator.rs"]
mod evaluator;
use common::urdf::{fixture, flat_matrix, floats, jacobian_terms};

const FIXTURES: [&str; 7] = [
    "arm4",
    "tree",
    "robots/ur5",
    "robots/panda",
    "robots/solo12",
    "robots/kinova",
    "robots/iiwa",
];

fn gravity(fx: &Value) -> [f64; 3] {
    let g = floats(&fx["gravity"]);
    [g[0], g[1], g[2]]
}

/// The larger of two errors, NaN if either is (`f64::max` would drop a NaN and pass).
fn worse(m: f64, d: f64) -> f64 {
    if d > m || d.is_nan() { d } else { m }
}

/// max |a − b| / max(1, max |b|); NaN if any entry is.
fn err(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| worse(m, (x - y).abs()))
        / scale
}

fn flat(m: &[Vec<f64>]) -> Vec<f64> {
    m.iter().flatten().copied().collect()
}

/// Every fixture's states as (q, q̇, its JSON).
fn states(fx: &Value) -> impl Iterator<Item = (Vec<f64>, Vec<f64>, &Value)> {
    (fx["states"].as_array().unwrap().iter()).map(|s| (floats(&s["q"]), floats(&s["qd"]), s))
}

/// Pinocchio's `crba` (symmetrised), `computeGeneralizedGravity` and `nonLinearEffects` − g
/// at every fixture state (50 per test robot, 20 per real robot; the Panda's finger is a mimic
/// joint, Solo 12 branches, the Kinova has continuous joints): the same to 1e-9 of
/// max(1, |ref|). Both sides are f64 recursions of a few hundred products per entry, so
/// rounding is ~1e-14 relative; 1e-9 still catches any wrong term, frame or sign (an error
/// in one inertia entry of a 10 g finger moves M by ≥ 1e-6).
#[test]
fn crba_and_rnea_equal_pinocchio() {
    for name in FIXTURES {
        let (tree, fx) = fixture(name);
        let model = tree.multibody(gravity(&fx));
        for (s, (q, qd, st)) in states(&fx).enumerate() {
            let m = flat(&crba(&model, &q));
            let m_ref: Vec<f64> = flat_matrix(&st["M"]);
            assert!(err(&m, &m_ref) < 1e-9, "{name} {s}: M {m:?} vs {m_ref:?}");
            let g = gravity_torques(&model, &q);
            let g_ref = floats(&st["g"]);
            assert!(err(&g, &g_ref) < 1e-9, "{name} {s}: g {g:?} vs {g_ref:?}");
            let c = coriolis(&model, &q, &qd);
            let c_ref = floats(&st["c"]);
            assert!(err(&c, &c_ref) < 1e-9, "{name} {s}: C q̇ {c:?} vs {c_ref:?}");
            // ID(q, q̇, 0) = C q̇ + g; ID is linear in q̈ with M as its matrix.
            let b = bias(&model, &q, &qd);
            let cg: Vec<f64> = c.iter().zip(&g).map(|(c, g)| c + g).collect();
            assert!(err(&b, &cg) < 1e-12, "{name} {s}: bias");
            let e0: Vec<f64> = (0..q.len())
                .map(|k| if k == 0 { 1.0 } else { 0.0 })
                .collect();
            let id: Vec<f64> = (inverse_dynamics(&model, &q, &qd, &e0).iter())
                .zip(&b)
                .map(|(t, b)| t - b)
                .collect();
            let col0: Vec<f64> = (0..q.len()).map(|r| m_ref[r * q.len()]).collect();
            assert!(err(&id, &col0) < 1e-9, "{name} {s}: ID − bias = M e₀");
        }
    }
}

fn random(rng: &mut Rng, n: usize, scale: f64) -> Vec<f64> {
    (0..n).map(|_| scale * rng.normal()).collect()
}

/// The model with random armatures (0.01 to 0.5, of the links' own order on these robots) as
/// parameters.
fn with_rotors(model: multibody::Model, rng: &mut Rng) -> multibody::Model {
    let a = (0..model.n).map(|_| rng.uniform_in(0.01, 0.5)).collect();
    model.with_armature(a)
}

/// Every fixture robot's model, with its name.
fn models() -> impl Iterator<Item = (&'static str, multibody::Model)> {
    FIXTURES.into_iter().map(|name| {
        let (tree, fx) = fixture(name);
        (name, tree.multibody(gravity(&fx)))
    })
}

/// ∂ID/∂(q, q̇) by RNEA over `Jet<64>` (forward mode through the body-frame
/// recursion): the independent reference for the analytic partials and the adjoint. Row i
/// is τᵢ's.
fn dual_id_partials(model: &multibody::Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let n = q.len();
    assert!(2 * n <= 64, "{n} coordinates");
    let x: Vec<Jet<64>> = Dual::seeded(&[q, qd].concat(), &1.0, 0..2 * n);
    let qddv: Vec<Jet<64>> = qdd.iter().map(|&a| Dual::constant(a)).collect();
    (inverse_dynamics(model, &x[..n], &x[n..], &qddv).iter())
        .map(|t| {
            (0..2 * n)
                .map(|k| t.tangent(k).copied().unwrap_or(0.0))
                .collect()
        })
        .collect()
}

/// A random (q, q̇, q̈) of n coordinates each.
fn random_state(rng: &mut Rng, n: usize, scale: f64) -> [Vec<f64>; 3] {
    std::array::from_fn(|_| random(rng, n, scale))
}

/// ‖M q̈ + C q̇ + g − τ‖∞ relative to the size of the terms summed (max(1, |τ|, Σⱼ|Mᵢⱼ q̈ⱼ|)):
/// a backward-stable solve leaves a residual of a few ε of that whatever M's condition.
fn residual(model: &multibody::Model, q: &[f64], qd: &[f64], tau: &[f64], qdd: &[f64]) -> f64 {
    let m = crba(model, q);
    let b = bias(model, q, qd);
    let mut worst = 0.0f64;
    let mut scale = 1.0f64;
    for i in 0..q.len() {
        let mq: f64 = (0..q.len()).map(|j| m[i][j] * qdd[j]).sum();
        let size: f64 = (0..q.len()).map(|j| (m[i][j] * qdd[j]).abs()).sum();
        scale = scale.max(size).max(tau[i].abs()).max(b[i].abs());
        worst = worse(worst, (mq + b[i] - tau[i]).abs());
    }
    worst / scale
}

/// q̈ = FD(q, q̇, τ) for random τ (N(0, 10²)) at every fixture state satisfies
/// M q̈ + C q̇ + g = τ to 1e-10 of the terms' size (f64 rounding through O(n) recursions
/// is ~1e-14 of it); without mimic joints ABA and CRBA + Cholesky agree to 1e-8 of
/// max(1, |q̈|) (the two differ by rounding amplified by M's condition, ≤ 1e4 here).
/// The kinetic energy (Σ ½ vᵢ·Iᵢvᵢ over the recursion's body velocities) and the potential
/// energy (Σ −m g·c over the composed placements) equal Pinocchio's at every fixture state,
/// to 1e-9 of max(1, |ref|) (rounding is ~1e-15; a wrong frame, first moment or sign moves
/// them by ≥ 1e-4 here), and ∂V/∂q over dual numbers is RNEA's gravity torque.
#[test]
fn energies_equal_pinocchio() {
    for name in FIXTURES {
        let (tree, fx) = fixture(name);
        let model = tree.multibody(gravity(&fx));
        for (s, (q, qd, st)) in states(&fx).enumerate() {
            let t = kinetic_energy(&model, &q, &qd);
            let t_ref = st["T"].as_f64().unwrap();
            assert!(err(&[t], &[t_ref]) < 1e-9, "{name} {s}: T {t} vs {t_ref}");
            let v = potential_energy(&model, &q);
            let v_ref = st["V"].as_f64().unwrap();
            assert!(err(&[v], &[v_ref]) < 1e-9, "{name} {s}: V {v} vs {v_ref}");
            if q.len() <= 16 {
                let qj: Vec<Jet<16>> = Dual::seeded(&q, &1.0, 0..q.len());
                let v = potential_energy(&model, &qj);
                let dv: Vec<f64> = (0..q.len())
                    .map(|k| v.tangent(k).copied().unwrap_or(0.0))
                    .collect();
                let g = gravity_torques(&model, &q);
                assert!(err(&dv, &g) < 1e-9, "{name} {s}: ∂V/∂q {dv:?} vs g {g:?}");
            }
        }
    }
}

/// With armatures too (every other state): ABA's pivots and CRBA's diagonal carry them.
#[test]
fn forward_dynamics_inverts_inverse_dynamics() {
    let mut rng = Rng::new(3);
    for name in FIXTURES {
        let (tree, fx) = fixture(name);
        let plain = tree.multibody(gravity(&fx));
        let rotors = with_rotors(plain.clone(), &mut rng);
        for (s, (q, qd, _)) in states(&fx).enumerate() {
            let model = if s % 2 == 0 { &plain } else { &rotors };
            let tau = random(&mut rng, q.len(), 10.0);
            let qdd = forward_dynamics(model, &q, &qd, &tau);
            let r = residual(model, &q, &qd, &tau, &qdd);
            assert!(r < 1e-10, "{name} {s}: residual {r}");
            let back = inverse_dynamics(model, &q, &qd, &qdd);
            assert!(
                err(&back, &tau) < 1e-8,
                "{name} {s}: ID(FD(τ)) {back:?} vs {tau:?}"
            );
            if !model.mimic {
                let other = crba_forward(model, &q, &qd, &tau);
                assert!(err(&aba(model, &q, &qd, &tau), &other) < 1e-8, "{name} {s}");
            }
        }
    }
}

/// For random physical inertias (θ ~ N(0, 1) per body: masses e^{2α} from 0.1 to 10, centres
/// of mass off the axes, full inertia tensors) and random states, CRBA and RNEA agree with
/// the Jacobian form's M = Σ JᵀIJ, ∂V/∂q and the Coriolis term of ∂M/∂q to 1e-9 of max(1, |ref|)
/// (two f64 evaluations of the same mechanics by different formulas).
#[test]
fn multibody_algorithms_agree_with_the_jacobian_form() {
    let mut rng = Rng::new(5);
    for name in FIXTURES {
        let (tree, fx) = fixture(name);
        let g = gravity(&fx);
        for _ in 0..5 {
            let inertias: Vec<Inertial> = (tree.bodies.iter())
                .map(|_| Inertial::from_theta(&std::array::from_fn(|_| rng.normal())))
                .collect();
            let model = tree.multibody_with(&inertias, g);
            let n = model.n;
            let q: Vec<f64> = (0..n).map(|_| rng.uniform_in(-PI, PI)).collect();
            let qd = random(&mut rng, n, 2.0);
            let (m, gv, c) = jacobian_terms(&tree, &inertias, &g, &q, &qd);
            let ours = flat(&crba(&model, &q));
            assert!(err(&ours, &m) < 1e-9, "{name}: M {ours:?} vs {m:?}");
            let ours = gravity_torques(&model, &q);
            assert!(err(&ours, &gv) < 1e-9, "{name}: g {ours:?} vs {gv:?}");
            let ours = coriolis(&model, &q, &qd);
            assert!(err(&ours, &c) < 1e-9, "{name}: C q̇ {ours:?} vs {c:?}");
        }
    }
}

/// ∂q̈/∂q and ∂q̈/∂q̇ (`forward_dynamics_derivatives`: −M⁻¹ ∂ID over dual numbers) against
/// central differences of the f64 forward dynamics, h = 1e-5: truncation h²/6·|q̈'''| ~ 1e-10
/// and rounding ε|q̈|·κ/h ~ 1e-16·10²·10⁴/1e-5 = 1e-5 at worst (κ: M's condition), so the
/// bound is 1e-4 of max(1, |∂q̈|) (measured: 3e-7); a wrong term shows at O(1). Dual numbers
/// are exact to rounding, so the other routes agree much closer: forward dynamics over `Dual`
/// (ABA, or CRBA + Cholesky) to 1e-9 (rounding amplified by M's condition).
#[test]
fn dual_derivatives_of_forward_dynamics_are_finite_differences() {
    let mut rng = Rng::new(9);
    for name in FIXTURES {
        let (tree, fx) = fixture(name);
        let model = tree.multibody(gravity(&fx));
        for (q, qd, _) in states(&fx).take(4) {
            let n = q.len();
            let tau = random(&mut rng, n, 5.0);
            let (qdd, dq, dqd) = forward_dynamics_derivatives(&model, &q, &qd, &tau);
            assert!(err(&qdd, &forward_dynamics(&model, &q, &qd, &tau)) < 1e-12);
            // −M⁻¹ ∂ID, and forward dynamics itself over dual numbers: the same derivatives
            // by different arithmetic, to rounding amplified by M's condition.
            let (_, dq2, dqd2) = fd_over_dual::<64>(&model, &q, &qd, &tau);
            assert!(
                err(&flat(&dq), &flat(&dq2)) < 1e-9,
                "{name}: ∂ID vs duals, ∂q"
            );
            assert!(
                err(&flat(&dqd), &flat(&dqd2)) < 1e-9,
                "{name}: ∂ID vs duals, ∂q̇"
            );
            let h = 1e-5;
            for k in 0..n {
                let at = |x: &[f64], s: f64| {
                    let mut y = x.to_vec();
                    y[k] += s;
                    y
                };
                let fd = |f: &dyn Fn(f64) -> Vec<f64>| -> Vec<f64> {
                    let (p, m) = (f(h), f(-h));
                    p.iter().zip(&m).map(|(p, m)| (p - m) / (2.0 * h)).collect()
                };
                let by_q = fd(&|s| forward_dynamics(&model, &at(&q, s), &qd, &tau));
                let by_qd = fd(&|s| forward_dynamics(&model, &q, &at(&qd, s), &tau));
                let col = |m: &[Vec<f64>]| m.iter().map(|r| r[k]).collect::<Vec<f64>>();
                let (a, b) = (col(&dq), col(&dqd));
                assert!(err(&a, &by_q) < 1e-4, "{name} ∂q̈/∂q{k}: {a:?} vs {by_q:?}");
                assert!(
                    err(&b, &by_qd) < 1e-4,
                    "{name} ∂q̈/∂q̇{k}: {b:?} vs {by_qd:?}"
                );
            }
            if !model.mimic {
                let n2 = 2 * n;
                let x: Vec<Jet<64>> = Dual::seeded(&[&q[..], &qd[..]].concat(), &1.0, 0..n2);
                let tv: Vec<Jet<64>> = tau.iter().map(|&t| Dual::constant(t)).collect();
                let via_crba = crba_forward(&model, &x[..n], &x[n..], &tv);
                for (i, x) in via_crba.iter().enumerate() {
                    let t: Vec<f64> = (0..n2)
                        .map(|k| x.tangent(k).copied().unwrap_or(0.0))
                        .collect();
                    let ours: Vec<f64> = dq[i].iter().chain(&dqd[i]).copied().collect();
                    assert!(err(&ours, &t) < 1e-8, "{name} row {i}: {ours:?} vs {t:?}");
                }
            }
        }
    }
}

/// A chain and a branch with two mimic joints that have offsets and carry bodies of their own:
/// j3 (revolute, about x) follows j1 times −1.5 plus 0.2 and carries a prismatic j4; j5
/// (prismatic, on the base) follows j2 times 0.7 minus 0.05.
fn mimic_robot() -> Tree {
    let link = |name: &str| {
        format!(
            r#"<link name="{name}"><inertial><origin xyz="0.05 0 0.1"/><mass value="1"/>
            <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>"#
        )
    };
    let joint = |name: &str, kind: &str, parent: &str, child: &str, extra: &str| {
        format!(
            r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>
            <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.5"/>{extra}</joint>"#
        )
    };
    let urdf = [
        r#"<robot name="mimics"><link name="base"/>"#.to_string(),
        link("l1"),
        link("l2"),
        link("l3"),
        link("l4"),
        link("l5"),
        joint("j1", "revolute", "base", "l1", r#"<axis xyz="0 0 1"/>"#),
        joint("j2", "revolute", "l1", "l2", r#"<axis xyz="0 1 0"/>"#),
        joint(
            "j3",
            "revolute",
            "l2",
            "l3",
            r#"<axis xyz="1 0 0"/><mimic joint="j1" multiplier="-1.5" offset="0.2"/>"#,
        ),
        joint("j4", "prismatic", "l3", "l4", r#"<axis xyz="0 1 1"/>"#),
        joint(
            "j5",
            "prismatic",
            "base",
            "l5",
            r#"<axis xyz="1 0 0"/><mimic joint="j2" multiplier="0.7" offset="-0.05"/>"#,
        ),
        "</robot>".to_string(),
    ]
    .concat();
    Tree::parse(&urdf, graybox::physics::MAX_DOF).unwrap()
}

/// On the mimic robot, with random inertias, CRBA and RNEA (contracted with G) equal
/// the Jacobian form's M, ∂V/∂q and Coriolis term to 1e-9 of max(1, |ref|), and forward dynamics
/// (CRBA + Cholesky) inverts them (tolerances as above).
#[test]
fn mimic_joints_with_offsets_agree_with_the_jacobian_form() {
    let tree = mimic_robot();
    assert_eq!(tree.coordinates.len(), 3);
    let g = [0.3, -1.0, -9.81];
    let mut rng = Rng::new(13);
    for _ in 0..20 {
        let inertias: Vec<Inertial> = (tree.bodies.iter())
            .map(|_| Inertial::from_theta(&std::array::from_fn(|_| rng.normal())))
            .collect();
        let model = tree.multibody_with(&inertias, g);
        assert!(model.mimic);
        let q: Vec<f64> = (0..3).map(|_| rng.uniform_in(-PI, PI)).collect();
        let qd = random(&mut rng, 3, 2.0);
        let (m, gv, c) = jacobian_terms(&tree, &inertias, &g, &q, &qd);
        assert!(err(&flat(&crba(&model, &q)), &m) < 1e-9, "M");
        assert!(err(&gravity_torques(&model, &q), &gv) < 1e-9, "g");
        assert!(err(&coriolis(&model, &q, &qd), &c) < 1e-9, "C q̇");
        let tau = random(&mut rng, 3, 10.0);
        let qdd = forward_dynamics(&model, &q, &qd, &tau);
        assert!(residual(&model, &q, &qd, &tau, &qdd) < 1e-10);
    }
}

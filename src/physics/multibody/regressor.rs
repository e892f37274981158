//! Inverse dynamics is linear in the bodies' inertial parameters (docs/robots.md#base-parameters):
//! τ = ID(q, q̇, q̈) = Y(q, q̇, q̈) π, with per body the ten standard parameters
//! π_b = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz), I about the body frame's
//! origin in its axes (the spatial inertia's A = I, B = [m c]×, C = m 𝟙). The base parameters
//! of a robot are the combinations of π that τ depends on: what motion data can identify.

use super::RigidBodyModel;
use super::rnea::inverse_dynamics;
use super::spatial::Inertia;

/// Standard parameters per body.
pub const PER_BODY: usize = 10;

/// Their names after the link's, in π's order.
pub const NAMES: [&str; PER_BODY] = [
    "mass", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz",
];

/// The spatial inertia of standard parameters `p`.
fn inertia_of(p: &[f64]) -> Inertia<f64> {
    let i = [[p[4], p[5], p[6]], [p[5], p[7], p[8]], [p[6], p[8], p[9]]];
    Inertia::rigid(p[0], &[p[1], p[2], p[3]], &i)
}

/// π of the model's bodies, body after body.
pub fn standard_parameters(model: &RigidBodyModel) -> Vec<f64> {
    (model.joints.iter())
        .flat_map(|j| {
            let (a, b) = (&j.inertia.a, &j.inertia.b);
            [
                j.inertia.c[0][0],
                b[2][1],
                b[0][2],
                b[1][0],
                a[0][0],
                a[0][1],
                a[0][2],
                a[1][1],
                a[1][2],
                a[2][2],
            ]
        })
        .collect()
}

/// The model with the bodies' inertias of π.
pub fn with_parameters(model: &RigidBodyModel, pi: &[f64]) -> RigidBodyModel {
    let mut m = model.clone();
    for (j, p) in m.joints.iter_mut().zip(pi.chunks(PER_BODY)) {
        j.inertia = inertia_of(p);
    }
    m
}

/// Y(q, q̇, q̈), n rows of 10·bodies columns: column k is ID with π = e_k (gravity included:
/// it acts on the inertia too). 10·bodies passes of RNEA, for identification and reports,
/// not for a training loop.
pub fn regressor(model: &RigidBodyModel, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let cols = PER_BODY * model.joints.len();
    let mut unit = with_parameters(model, &vec![0.0; cols]);
    let mut y = vec![vec![0.0; cols]; q.len()];
    for k in 0..cols {
        let (body, p) = (k / PER_BODY, k % PER_BODY);
        let mut e = [0.0; PER_BODY];
        e[p] = 1.0;
        let before = std::mem::replace(&mut unit.joints[body].inertia, inertia_of(&e));
        for (row, t) in y.iter_mut().zip(inverse_dynamics(&unit, q, qd, qdd)) {
            row[k] = t;
        }
        unit.joints[body].inertia = before;
    }
    y
}

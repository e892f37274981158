//! Inverse dynamics is linear in the bodies' inertial parameters (docs/robots.md#base-parameters):
//! τ = ID(q, q̇, q̈) = Y(q, q̇, q̈) π, with per body the ten standard parameters
//! π_b = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz), I about the body frame's
//! origin in its axes (the spatial inertia's A = I, B = [m c]×, C = m 𝟙). The base parameters
//! of a robot are the combinations of π that τ depends on: what motion data can identify.

use super::Model;
use super::rnea::inverse_dynamics;
use super::spatial::{Inertial, PER_BODY};

/// π of the model's bodies, body after body, then its armatures when it has them.
pub fn standard_parameters(model: &Model) -> Vec<f64> {
    let bodies = model.bodies.iter().flat_map(|b| b.inertia.standard());
    bodies
        .chain(model.armature.iter().flatten().copied())
        .collect()
}

/// The model with the bodies' inertias (and the armatures) of π.
pub fn with_parameters(model: &Model, pi: &[f64]) -> Model {
    assert_eq!(pi.len(), model.parameter_count(), "π's length");
    let mut m = model.clone();
    for (j, p) in m.bodies.iter_mut().zip(pi.chunks(PER_BODY)) {
        j.inertia = Inertial::of_standard(p);
    }
    if let Some(a) = &mut m.armature {
        a.copy_from_slice(&pi[PER_BODY * model.bodies.len()..]);
    }
    m
}

/// Y(q, q̇, q̈), n rows of `parameter_count` columns: column k is ID with π = e_k (gravity
/// included: it acts on the inertia too), an armature's column its coordinate's q̈.
/// 10·bodies passes of RNEA, for identification and reports, not for a training loop.
pub fn regressor(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
    let (bodies, cols) = (PER_BODY * model.bodies.len(), model.parameter_count());
    let mut unit = with_parameters(model, &vec![0.0; cols]);
    let mut y = vec![vec![0.0; cols]; q.len()];
    for k in 0..bodies {
        let (body, p) = (k / PER_BODY, k % PER_BODY);
        let mut e = [0.0; PER_BODY];
        e[p] = 1.0;
        let before = std::mem::replace(&mut unit.bodies[body].inertia, Inertial::of_standard(&e));
        for (row, t) in y.iter_mut().zip(inverse_dynamics(&unit, q, qd, qdd)) {
            row[k] = t;
        }
        unit.bodies[body].inertia = before;
    }
    if cols > bodies {
        for (j, (row, a)) in y.iter_mut().zip(qdd).enumerate() {
            row[bodies + j] = *a;
        }
    }
    y
}

//! The robot's energies over its forward kinematics (docs/robots.md#multibody-dynamics):
//! kinetic T = Σ ½ vᵢ · Iᵢ vᵢ with each body's spatial velocity, and potential
//! V = −Σ g · (mᵢ pᵢ + E₀ᵢᵀ hᵢ) with each body's placement in the root frame: O(n) each.

use super::Model;
use super::kinematics::{Placed, placements, velocities};
use super::spatial::{add, cdot, mtv};
use crate::physics::scalar::Scalar;

/// ½ q̇ᵀ M(q) q̇, without forming M.
pub fn kinetic_energy<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> S {
    let zero = q[0].lift(0.0);
    let mut twice = zero.clone();
    for (j, v) in model.bodies.iter().zip(velocities(model, q, qd)) {
        twice = twice + v.dot(&j.inertia.apply_const(&v, &zero));
    }
    twice.scale(0.5)
}

/// V(q) of gravity, zero at the root frame's origin (as `urdf::assembled::potential`).
pub fn potential_energy<S: Scalar>(model: &Model, q: &[S]) -> S {
    let zero = q[0].lift(0.0);
    let mut v = zero.clone();
    for (j, Placed { e, p }) in model.bodies.iter().zip(placements(model, q)) {
        let (m, h) = (j.inertia.mass(), j.inertia.first_moment());
        let moment = add(&p.map(|x| x.scale(m)), &mtv(&e, &h.map(|x| zero.lift(x))));
        v = v - cdot(&model.gravity, &moment, &zero);
    }
    v
}

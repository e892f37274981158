//! The robot's energies over its forward kinematics (docs/robots.md#multibody-dynamics):
//! kinetic T = Σ ½ vᵢ · Iᵢ vᵢ with each body's spatial velocity, and potential
//! V = −Σ g · (mᵢ pᵢ + E₀ᵢᵀ hᵢ) with each body's placement in the root frame: O(n) each, V
//! also with the bodies' masses and first moments over any scalar in place of the model's (a
//! URDF template's trainable values, docs/robots.md#mass-matrix-and-potential).

use super::Model;
use super::data::Data;
use super::spatial::six;
use super::spatial::{V3, cdot, dot, mv};
use crate::physics::scalar::Scalar;

/// ½ q̇ᵀ M(q) q̇, without forming M: Σ ½ vᵢ · Iᵢ vᵢ from the root-frame velocities and
/// momenta `Data::kinematics` leaves.
pub fn kinetic_energy<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> S {
    let mut data = Data::for_state(model, q);
    data.kinematics(model, q, qd);
    let mut twice = q[0].lift(0.0);
    for (v, h) in data.v.iter().zip(&data.momentum) {
        twice = twice + six::dot(v, h);
    }
    for (c, v) in qd.iter().enumerate() {
        twice = twice + v.square().scale(model.armature_of(c));
    }
    twice.scale(0.5)
}

/// V(q) of gravity, zero at the root frame's origin.
pub fn potential_energy<S: Scalar>(model: &Model, q: &[S]) -> S {
    let zero = q[0].lift(0.0);
    let moments: Vec<(S, V3<S>)> = (model.bodies.iter())
        .map(|j| {
            let h = j.inertia.h.map(|x| zero.lift(x));
            (zero.lift(j.inertia.mass), h)
        })
        .collect();
    potential_energy_of(model, q, &moments)
}

/// V(q) with each body's mass m and first moment h = m c (in its frame) given over any
/// scalar in place of the model's. Of a body's placement V needs only gravity in its axes,
/// γᵢ = E₀ᵢ g, and its height along gravity, g·pᵢ, so −Σ (mᵢ g·pᵢ + γᵢ·hᵢ) composes those from
/// the parent's, γᵢ = E γₚ and g·pᵢ = g·pₚ + γₚ·r: a 3-vector a body where the placement is a
/// 3×3 product (on the training tape of a model whose M is a network, a fifth of the nodes
/// of V over `Data::placements`).
pub fn potential_energy_of<S: Scalar>(model: &Model, q: &[S], moments: &[(S, V3<S>)]) -> S {
    let zero = q[0].lift(0.0);
    let g = &model.gravity;
    let mut felt: Vec<(V3<S>, S)> = Vec::with_capacity(model.bodies.len());
    let mut v = zero.clone();
    for (j, (m, h)) in model.bodies.iter().zip(moments) {
        let x = j.placement(q, &zero);
        let (gamma, height) = match j.parent {
            Some(k) => {
                let (gp, hp) = &felt[k];
                (mv(&x.e, gp), hp.clone() + dot(gp, &x.r))
            }
            None => (x.e.map(|row| cdot(g, &row, &zero)), cdot(g, &x.r, &zero)),
        };
        v = v - (m.clone() * height.clone() + dot(&gamma, h));
        felt.push((gamma, height));
    }
    v
}

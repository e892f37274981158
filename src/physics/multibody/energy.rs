//! The robot's energies by recursions over the tree (docs/robots.md#multibody-dynamics):
//! kinetic T = Σ ½ vᵢ · Iᵢ vᵢ with each body's spatial velocity from RNEA's forward pass, and
//! potential V = −Σ g · (mᵢ pᵢ + E₀ᵢᵀ hᵢ) with each body's placement in the root frame
//! (E₀ᵢ root axes to body axes, pᵢ its origin) composed from its parent's: O(n) each.

use super::Model;
use super::spatial::{M3, Motion, V3, add, cdot, mtv};
use crate::physics::scalar::Scalar;

/// ½ q̇ᵀ M(q) q̇, without forming M.
pub fn kinetic_energy<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> S {
    let zero = q[0].lift(0.0);
    let mut vs: Vec<Motion<S>> = Vec::with_capacity(model.bodies.len());
    let mut twice = zero.clone();
    for j in &model.bodies {
        let x = j.xform(&j.value(q), &zero);
        let vj = j.motion(&j.rate(qd), &zero);
        let v = match j.parent {
            Some(p) => x.motion(&vs[p]).plus(&vj),
            None => vj,
        };
        twice = twice + v.dot(&j.inertia.apply_const(&v, &zero));
        vs.push(v);
    }
    twice.scale(0.5)
}

/// V(q) of gravity, zero at the root frame's origin (as `urdf::assembled::potential`).
pub fn potential_energy<S: Scalar>(model: &Model, q: &[S]) -> S {
    let zero = q[0].lift(0.0);
    let mut placed: Vec<(M3<S>, V3<S>)> = Vec::with_capacity(model.bodies.len());
    let mut v = zero.clone();
    for j in &model.bodies {
        let x = j.xform(&j.value(q), &zero);
        let (e, p) = match j.parent {
            // E₀ᵢ = E E₀ₚ; pᵢ = pₚ + E₀ₚᵀ r.
            Some(k) => {
                let (ep, pp) = &placed[k];
                let e: M3<S> = std::array::from_fn(|r| {
                    std::array::from_fn(|c| {
                        (0..3)
                            .map(|l| x.e[r][l].clone() * ep[l][c].clone())
                            .reduce(|a, b| a + b)
                            .expect("three terms")
                    })
                });
                (e, add(pp, &mtv(ep, &x.r)))
            }
            None => (x.e, x.r),
        };
        // The body's first moment h from B = [h]×, its mass from C = m 𝟙.
        let (m, h) = (j.inertia.mass(), j.inertia.first_moment());
        let moment = add(
            &p.clone().map(|x| x.scale(m)),
            &mtv(&e, &h.map(|x| zero.lift(x))),
        );
        v = v - cdot(&model.gravity, &moment, &zero);
        placed.push((e, p));
    }
    v
}

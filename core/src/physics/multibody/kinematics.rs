//! Forward kinematics (docs/robots.md#multibody-dynamics): each body's spatial velocity and
//! its placement in the root frame, composed from its parent's in one pass from the root,
//! for any algorithm that needs them (the energies; a centroidal momentum matrix would).

use super::Model;
use super::spatial::{M3, Motion, V3, add, mtv};
use crate::physics::scalar::Scalar;

/// A body's placement in the root frame: E₀ turns root axes into the body's, p is its origin.
pub struct Placed<S> {
    pub e: M3<S>,
    pub p: V3<S>,
}

/// Each body's spatial velocity in its own coordinates (RNEA's forward pass).
pub fn velocities<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> Vec<Motion<S>> {
    let zero = q[0].lift(0.0);
    let mut vs: Vec<Motion<S>> = Vec::with_capacity(model.bodies.len());
    for j in &model.bodies {
        let x = j.placement(q, &zero);
        let vj = j.joint_motion(qd, &zero);
        let v = match j.parent {
            Some(p) => x.motion(&vs[p]).plus(&vj),
            None => vj,
        };
        vs.push(v);
    }
    vs
}

/// Each body's placement in the root frame: E₀ᵢ = E E₀ₚ, pᵢ = pₚ + E₀ₚᵀ r.
pub fn placements<S: Scalar>(model: &Model, q: &[S]) -> Vec<Placed<S>> {
    let zero = q[0].lift(0.0);
    let mut placed: Vec<Placed<S>> = Vec::with_capacity(model.bodies.len());
    for j in &model.bodies {
        let x = j.placement(q, &zero);
        let next = match j.parent {
            Some(k) => {
                let Placed { e: ep, p: pp } = &placed[k];
                let e: M3<S> = std::array::from_fn(|r| {
                    std::array::from_fn(|c| {
                        (0..3)
                            .map(|l| x.e[r][l].clone() * ep[l][c].clone())
                            .reduce(|a, b| a + b)
                            .expect("three terms")
                    })
                });
                Placed {
                    e,
                    p: add(pp, &mtv(ep, &x.r)),
                }
            }
            None => Placed { e: x.e, p: x.r },
        };
        placed.push(next);
    }
    placed
}

//! A rigid body in a vertical plane whose heading is a unit complex number: q = (x, y,
//! cos θ, sin θ), v = (ẋ, ẏ, ω), so nq = 4 and nv = 3 (docs/dynamics.md#configuration-space).
//! (x, y) is a reference point on the body; the centre of mass sits a distance d ahead of it
//! along the body's axis. Inputs are a force (u₁, u₂) in the body's frame at the reference
//! point and a torque u₃; the motion is damped linearly.
//!
//! With p_c = (x + d c, y + d s), T = ½ m |ṗ_c|² + ½ I ω² and V = m g (y + d s):
//!
//! ```text
//! M(q) = [[m, 0, −m d s], [0, m, m d c], [−m d s, m d c, I + m d²]]
//! F = (c u₁ − s u₂ + η_xy ẋ, s u₁ + c u₂ + η_xy ẏ, u₃ + η_θ ω)
//! ```
//!
//! M depends on the heading, so its Coriolis term exercises the derivatives along the
//! rotation's tangent, (∂c, ∂s)/∂θ = (−s, c).

use crate::arena::{AVec, Arena, avec};
use crate::physics::scalar::Scalar;
use crate::physics::space::{Joint, Space};

/// The joints: the reference point's two coordinates and the heading.
pub fn space() -> Space {
    Space::new(vec![Joint::Real, Joint::Real, Joint::Circle])
}

pub fn mass_in<'a, S: Scalar>(a: &'a Arena, p: &[S], q: &[S]) -> AVec<'a, AVec<'a, S>> {
    let (m, i, d) = (&p[0], &p[1], &p[2]);
    let (c, s) = (&q[2], &q[3]);
    let md = m.clone() * d.clone();
    let m13 = -(md.clone() * s.clone());
    let m23 = md.clone() * c.clone();
    let m33 = i.clone() + md * d.clone();
    avec![in a;
        avec![in a; m.clone(), m.lift(0.0), m13.clone()],
        avec![in a; m.lift(0.0), m.clone(), m23.clone()],
        avec![in a; m13, m23, m33],
    ]
}

pub fn potential<S: Scalar>(p: &[S], q: &[S]) -> S {
    let (m, d, g) = (&p[0], &p[2], &p[3]);
    m.clone() * g.clone() * (q[1].clone() + d.clone() * q[3].clone())
}

pub fn forces_in<'a, S: Scalar>(a: &'a Arena, p: &[S], q: &[S], v: &[S], u: &[S]) -> AVec<'a, S> {
    let (exy, eth) = (&p[4], &p[5]);
    let (c, s) = (&q[2], &q[3]);
    avec![in a;
        c.clone() * u[0].clone() - s.clone() * u[1].clone() + exy.clone() * v[0].clone(),
        s.clone() * u[0].clone() + c.clone() * u[1].clone() + exy.clone() * v[1].clone(),
        u[2].clone() + eth.clone() * v[2].clone(),
    ]
}

//! A model's configuration space (docs/dynamics.md#configuration-space): a state is
//! x = [q, v] with nq configuration values and nv velocities, and every velocity,
//! acceleration, force and Jacobian lives in the tangent space (nv wide). A space is a list of
//! joints, each with its own `integrate(q, v·dt)` and `difference(q0, q1)`, as Pinocchio,
//! MuJoCo and Crocoddyl separate the two. For a coordinate on the line (every model before
//! nq and nv) both are plain addition and subtraction, written as the integrators always
//! computed them, so that such a model's answers stay what they were to the bit.

use std::ops::Range;

use serde::{Deserialize, Serialize};

use super::dual::{Dual, Tangents};
use super::scalar::Scalar;
use crate::arena::{AVec, Arena};

/// One joint of a configuration space.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Joint {
    /// A coordinate on the real line: a length, or an angle that is compared as a number.
    Real,
    /// An angle kept as a number (nq = nv = 1): integrated and differenced as one, while the
    /// networks see (sin q, cos q) and the loss compares it on the circle, 2(1 − cos Δ).
    Angle,
    /// A rotation in the plane as a unit complex number (cos θ, sin θ): nq = 2, nv = 1, with
    /// no wrap-around anywhere (a planar body's heading).
    Circle,
}

impl Joint {
    pub fn nq(self) -> usize {
        match self {
            Joint::Real | Joint::Angle => 1,
            Joint::Circle => 2,
        }
    }

    pub fn nv(self) -> usize {
        1
    }

    pub fn name(self) -> &'static str {
        match self {
            Joint::Real => "real",
            Joint::Angle => "angle",
            Joint::Circle => "circle",
        }
    }
}

/// A joint with where its values sit in q and in v.
#[derive(Debug, Clone)]
pub struct Placed {
    pub joint: Joint,
    pub q: Range<usize>,
    pub v: usize,
}

/// The configuration space of a model: its joints in coordinate order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Space {
    joints: Vec<Joint>,
    nq: usize,
}

impl Space {
    pub fn new(joints: Vec<Joint>) -> Self {
        let nq = joints.iter().map(|j| j.nq()).sum();
        Self { joints, nq }
    }

    /// n coordinates on the line, those `periodic` marks as angles (an empty `periodic`
    /// marks none): the space of every model file written before nq and nv.
    pub fn flat(n: usize, periodic: &[bool]) -> Self {
        let angle = |k: usize| periodic.get(k).copied().unwrap_or(false);
        let joints = (0..n)
            .map(|k| if angle(k) { Joint::Angle } else { Joint::Real })
            .collect();
        Self::new(joints)
    }

    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Configuration values.
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// Velocities: the tangent space's dimension.
    pub fn nv(&self) -> usize {
        self.joints.len()
    }

    /// Whether q and v are both n numbers added as numbers (no joint of nq ≠ nv).
    pub fn is_flat(&self) -> bool {
        self.nq == self.nv()
    }

    /// Whether every joint is a plain coordinate on the line (no angle, no rotation): the
    /// networks then read q standardized as it is.
    pub fn is_real(&self) -> bool {
        self.joints.iter().all(|j| *j == Joint::Real)
    }

    /// The configuration at the origin: every coordinate 0, a rotation at (1, 0).
    pub fn origin(&self) -> Vec<f64> {
        let mut q = Vec::with_capacity(self.nq + self.nv());
        for j in &self.joints {
            match j {
                Joint::Real | Joint::Angle => q.push(0.0),
                Joint::Circle => q.extend([1.0, 0.0]),
            }
        }
        q
    }

    /// The state [q, v] at the origin, at rest.
    pub fn origin_state(&self) -> Vec<f64> {
        let mut x = self.origin();
        x.resize(self.nq + self.nv(), 0.0);
        x
    }

    /// Which coordinates are angles, as files before nq and nv stored it (empty: none; only
    /// meaningful for a flat space).
    pub fn periodic(&self) -> Vec<bool> {
        let angles: Vec<bool> = self.joints.iter().map(|j| *j == Joint::Angle).collect();
        if angles.contains(&true) {
            angles
        } else {
            vec![]
        }
    }

    /// Whether velocity k is an angle's.
    pub fn is_angle(&self, k: usize) -> bool {
        self.joints.get(k) == Some(&Joint::Angle)
    }

    /// Each joint with its q values and its velocity.
    pub fn placed(&self) -> impl Iterator<Item = Placed> + '_ {
        let mut at = 0;
        self.joints.iter().enumerate().map(move |(v, &joint)| {
            let q = at..at + joint.nq();
            at = q.end;
            Placed { joint, q, v }
        })
    }

    /// The width of a network input made of q: one per coordinate on the line, two for an
    /// angle ((sin q, cos q)) and for a rotation ((cos θ, sin θ)).
    pub fn q_features(&self) -> usize {
        self.joints
            .iter()
            .map(|j| if *j == Joint::Real { 1 } else { 2 })
            .sum()
    }

    /// integrate(q, a·v) appended to `out`: q moved along the tangent vector a·v.
    pub fn integrate_into<S: Scalar>(&self, q: &[S], a: f64, v: &[S], out: &mut impl Extend<S>) {
        if self.is_flat() {
            // The integrators' axpy, as every flat model's answers were recorded.
            out.extend(q.iter().zip(v).map(|(q, v)| q.clone() + v.scale(a)));
            return;
        }
        for p in self.placed() {
            let dv = v[p.v].scale(a);
            match p.joint {
                Joint::Real | Joint::Angle => out.extend([q[p.q.start].clone() + dv]),
                Joint::Circle => {
                    let (c, s) = (&q[p.q.start], &q[p.q.start + 1]);
                    let (cos, sin) = (dv.cos(), dv.sin());
                    let c1 = c.clone() * cos.clone() - s.clone() * sin.clone();
                    let s1 = s.clone() * cos + c.clone() * sin;
                    out.extend([c1, s1]);
                }
            }
        }
    }

    /// integrate(q, v) as a vector.
    pub fn integrate<S: Scalar>(&self, q: &[S], v: &[S]) -> Vec<S> {
        let mut out = Vec::with_capacity(self.nq);
        self.integrate_into(q, 1.0, v, &mut out);
        out
    }

    /// difference(q0, q1): the tangent vector v with integrate(q0, v) = q1 (the shortest
    /// rotation for a circle joint).
    pub fn difference(&self, q0: &[f64], q1: &[f64]) -> Vec<f64> {
        self.placed()
            .map(|p| match p.joint {
                Joint::Real | Joint::Angle => q1[p.q.start] - q0[p.q.start],
                Joint::Circle => {
                    let (c0, s0) = (q0[p.q.start], q0[p.q.start + 1]);
                    let (c1, s1) = (q1[p.q.start], q1[p.q.start + 1]);
                    (c0 * s1 - s0 * c1).atan2(c0 * c1 + s0 * s1)
                }
            })
            .collect()
    }

    /// x1 ⊖ x0 for states x = [q, v]: [difference(q0, q1), v1 − v0].
    pub fn state_difference(&self, x0: &[f64], x1: &[f64]) -> Vec<f64> {
        let nq = self.nq;
        let mut d = self.difference(&x0[..nq], &x1[..nq]);
        d.extend(x1[nq..].iter().zip(&x0[nq..]).map(|(a, b)| a - b));
        d
    }

    /// x ⊕ δ for states x = [q, v] and tangents δ = [δq, δv].
    pub fn state_integrate(&self, x: &[f64], d: &[f64]) -> Vec<f64> {
        let (nq, nv) = (self.nq, self.nv());
        let mut out = self.integrate(&x[..nq], &d[..nv]);
        out.extend(x[nq..].iter().zip(&d[nv..]).map(|(x, d)| x + d));
        out
    }

    /// Rows of states [q, v] moved onto the space: each rotation's (c, s) scaled to unit
    /// length. An ensemble's mean of unit complex numbers lies inside the circle; its
    /// projection is their mean on the circle (the extrinsic mean, arg Σ z_k). A no-op on a
    /// flat space, so such a mean stays the plain average to the bit.
    pub fn project_states(&self, x: &mut [f64]) {
        if self.is_flat() {
            return;
        }
        for row in x.chunks_mut(self.nq + self.nv()) {
            for p in self.placed().filter(|p| p.joint == Joint::Circle) {
                let (c, s) = (row[p.q.start], row[p.q.start + 1]);
                let r = c.hypot(s);
                if r > 0.0 {
                    row[p.q.start] = c / r;
                    row[p.q.start + 1] = s / r;
                }
            }
        }
    }

    /// A state [q, v] in the chart where every joint is one number ([θ, v], 2nv wide): a
    /// rotation (c, s) by its angle θ = atan2(s, c) ∈ (−π, π], every other value as it is.
    /// For today's joints (the line and the circle, both commutative) integrate is addition
    /// in this chart, so a problem solved in it is solved on the space.
    pub fn state_chart(&self, x: &[f64]) -> Vec<f64> {
        let mut c = Vec::with_capacity(2 * self.nv());
        for p in self.placed() {
            c.push(match p.joint {
                Joint::Real | Joint::Angle => x[p.q.start],
                Joint::Circle => x[p.q.start + 1].atan2(x[p.q.start]),
            });
        }
        c.extend_from_slice(&x[self.nq..]);
        c
    }

    /// The state at chart coordinates [θ, v] ([`Space::state_chart`]'s inverse).
    pub fn state_from_chart(&self, c: &[f64]) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.nq + self.nv());
        for p in self.placed() {
            match p.joint {
                Joint::Real | Joint::Angle => x.push(c[p.v]),
                Joint::Circle => x.extend([c[p.v].cos(), c[p.v].sin()]),
            }
        }
        x.extend_from_slice(&c[self.nv()..]);
        x
    }

    /// q as dual numbers in the tangent directions `dirs` (velocity indices):
    /// q ⊕ ε e_k for each k in `dirs`, to first order. A line's coordinate k carries `one` in
    /// direction k; a rotation (c, s) carries (−s, c) in its velocity's direction.
    pub fn seeded_in<'a, S: Scalar, T: Tangents<S>>(
        &self,
        a: &'a Arena,
        q: &[S],
        one: &S,
        dirs: Range<usize>,
    ) -> AVec<'a, Dual<S, T>> {
        if self.is_flat() {
            return Dual::seeded_in(a, q, one, dirs);
        }
        let mut out = AVec::with_capacity_in(self.nq, a);
        for p in self.placed() {
            let var = |v: &S, seed: S| match dirs.contains(&p.v) {
                true => Dual::variable(v.clone(), p.v - dirs.start, dirs.len(), seed),
                false => Dual::constant(v.clone()),
            };
            match p.joint {
                Joint::Real | Joint::Angle => out.push(var(&q[p.q.start], one.clone())),
                Joint::Circle => {
                    let (c, s) = (&q[p.q.start], &q[p.q.start + 1]);
                    out.push(var(c, -(s.clone() * one.clone())));
                    out.push(var(s, c.clone() * one.clone()));
                }
            }
        }
        out
    }

    /// The tangent of a change dq of q at `q` (rows of `width` derivatives each, nq of them),
    /// appended to `out` as nv rows: ∂ difference(q, q + dq)/∂dq at dq = 0 applied to them.
    /// A line's row is its own; a rotation's is (c·ds − s·dc)/(c² + s²).
    pub fn tangent_rows(&self, q: &[f64], rows: &[f64], width: usize, out: &mut impl Extend<f64>) {
        let row = |i: usize| &rows[width * i..][..width];
        for p in self.placed() {
            match p.joint {
                Joint::Real | Joint::Angle => out.extend(row(p.q.start).iter().copied()),
                Joint::Circle => {
                    let (c, s) = (q[p.q.start], q[p.q.start + 1]);
                    let r2 = c * c + s * s;
                    let (dc, ds) = (row(p.q.start), row(p.q.start + 1));
                    out.extend(dc.iter().zip(ds).map(|(dc, ds)| (c * ds - s * dc) / r2));
                }
            }
        }
    }

    /// The basis of q's changes along each velocity at `q`: ∂ integrate(q, v)/∂v at v = 0,
    /// nq rows of nv.
    pub fn integrate_basis(&self, q: &[f64]) -> Vec<f64> {
        let nv = self.nv();
        let mut out = vec![0.0; self.nq * nv];
        for p in self.placed() {
            match p.joint {
                Joint::Real | Joint::Angle => out[p.q.start * nv + p.v] = 1.0,
                Joint::Circle => {
                    out[p.q.start * nv + p.v] = -q[p.q.start + 1];
                    out[(p.q.start + 1) * nv + p.v] = q[p.q.start];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests;

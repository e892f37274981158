//! A URDF robot's joint forces: its actuators' inputs (through their gain and offset when it
//! has them), viscous damping and smoothed Coulomb friction per joint.

use super::parameters::{PER_BODY, PER_JOINT};
use super::template::UrdfTemplate;
use crate::arena::{AVec, Arena, CollectIn, avec};
use crate::physics::scalar::Scalar;

impl UrdfTemplate {
    /// F = S (g∘u + o) − d∘q̇ − f∘tanh(q̇/ε), per joint (g = 1, o = 0 without the groups); a
    /// mimic joint's force enters the coordinate it follows times its multiplier, and moves
    /// at the multiplier times its velocity.
    pub fn forces<S: Scalar>(&self, p: &[S], q: &[S], qd: &[S], u: &[S]) -> Vec<S> {
        self.forces_in(&Arena::new(), p, q, qd, u).to_vec()
    }

    /// [`UrdfTemplate::forces`] in an arena.
    pub fn forces_in<'a, S: Scalar>(
        &self,
        a: &'a Arena,
        p: &[S],
        _q: &[S],
        qd: &[S],
        u: &[S],
    ) -> AVec<'a, S> {
        self.forces_of(a, p, qd, Some(u))
    }

    /// The joints' own forces, −d∘q̇ − f∘tanh(q̇/ε): F without the actuators (their offsets
    /// included), the part an energy report calls friction.
    pub fn passive_forces_in<'a, S: Scalar>(&self, a: &'a Arena, p: &[S], qd: &[S]) -> AVec<'a, S> {
        self.forces_of(a, p, qd, None)
    }

    fn forces_of<'a, S: Scalar>(
        &self,
        a: &'a Arena,
        p: &[S],
        qd: &[S],
        u: Option<&[S]>,
    ) -> AVec<'a, S> {
        let mut out: AVec<Option<S>> = avec![in a; None; self.n()];
        let per_eps = 1.0 / self.doc.coulomb_eps;
        for (i, b) in self.tree.bodies.iter().enumerate() {
            let k = self.nb() * PER_BODY + PER_JOINT * i;
            let (d, f) = (&p[k], &p[k + 1]);
            let c = b.drive.coordinate;
            let g = b.drive.multiplier;
            let v = if g == 1.0 {
                qd[c].clone()
            } else {
                qd[c].scale(g)
            };
            let mut e = -(d.clone() * v.clone()) - f.clone() * v.scale(per_eps).tanh();
            if g != 1.0 {
                e = e.scale(g);
            }
            out[c] = Some(match out[c].take() {
                Some(sum) => sum + e,
                None => e,
            });
        }
        let (gain, offset) = (self.effort_gain(p), self.effort_offset(p));
        for (k, &c) in self.actuated.iter().enumerate() {
            let Some(u) = u else { break };
            let mut e = match gain.get(k) {
                Some(g) => g.clone() * u[k].clone(),
                None => u[k].clone(),
            };
            if let Some(o) = offset.get(k) {
                e = e + o.clone();
            }
            out[c] = out[c].take().map(|f| f + e);
        }
        (out.into_iter())
            .map(|f| f.expect("every coordinate has its own joint"))
            .collect_in(a)
    }
}

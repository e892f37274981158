//! The workspace of the multibody algorithms (docs/robots.md#the-data-workspace), as
//! Pinocchio's `Data`: every per-configuration quantity of one state, computed once in the
//! root frame and shared by kinematics, CRBA, RNEA, ABA, the derivatives of RNEA and the
//! adjoint. It is generic over the scalar, so each algorithm is written once and runs on f64
//! (fast: plain arrays whose `clone` is a copy) and on the forward-mode types (dual numbers,
//! jets, batch columns). Its vectors only grow, so a workspace reused across calls (one per
//! thread for f64: `thread_data::with_data`) allocates nothing after its first.
//!
//! In the root frame a body's joint axis S, velocity v and acceleration a (the root's −g, so
//! gravity needs no term of its own) compose by sums down the tree, v = v_parent + S θ̇ and
//! a = a_parent + S θ̈ + d θ̇ with d = v_parent × S, and every body's force f = I a + v ×* I v
//! (I in the root frame) adds up the tree without transforms. That is what makes the analytic
//! derivatives of RNEA (`derivatives`) a sum of dot products.

use super::Model;
use super::spatial::six::{
    M6, V6, Variation, add, add_assign, add_scaled, apply, cross, cross_force, dot,
    inertia_to_root, motion_to_root, zeros, zeros_m6,
};
use super::spatial::{Inertial, M3, V3};
use crate::linalg::cholesky;
use crate::physics::scalar::Scalar;

/// Quantities at one state; see the module comment. Body-indexed vectors follow
/// `Model::bodies`, matrices over the coordinates are n×n row-major.
#[derive(Debug, Clone)]
pub struct Data<S = f64> {
    n: usize,
    /// Root axes to the body's, and the body's origin in the root frame.
    pub(super) rot: Vec<M3<S>>,
    pub(super) pos: Vec<V3<S>>,
    /// Joint axis, velocity, d = v_parent × S, acceleration: all in the root frame.
    pub(super) s: Vec<V6<S>>,
    pub(super) v: Vec<V6<S>>,
    pub(super) d: Vec<V6<S>>,
    pub(super) a: Vec<V6<S>>,
    /// The root's acceleration: −g, or zero for the terms without gravity.
    pub(super) a0: V6<S>,
    /// Joint velocities θ̇ (a mimic joint's from its coordinate's).
    pub(super) rate: Vec<S>,
    /// The body's inertia in the root frame, its momentum I v, and the composite inertia of
    /// the subtree it carries.
    pub(super) inertia: Vec<M6<S>>,
    pub(super) momentum: Vec<V6<S>>,
    pub(super) composite: Vec<M6<S>>,
    /// After `accelerations`: the force of each body's subtree.
    pub(super) force: Vec<V6<S>>,
    /// M(q), its Cholesky factor (lower), C q̇ + g (or τ after `torques`), and q̈.
    pub mass: Vec<S>,
    pub(super) chol: Vec<S>,
    pub bias: Vec<S>,
    pub qdd: Vec<S>,
    /// ∂ID/∂q and ∂ID/∂q̇ (row i is τᵢ's), after `id_derivatives`.
    pub id_dq: Vec<S>,
    pub id_dqd: Vec<S>,
    /// Per body, scratch of `id_derivatives`: α = a_parent × S + v_parent × d, and the composite
    /// variation B of the body force in v.
    pub(super) alpha: Vec<V6<S>>,
    pub(super) variation: Vec<Variation<S>>,
    /// Per body, scratch of the adjoint: w = Σ S λ over its path from the root, and the sums
    /// over its subtree of λ Iᶜ S and λ Bᶜᵀ S.
    pub(super) carried: Vec<V6<S>>,
    pub(super) reach_i: Vec<V6<S>>,
    pub(super) reach_b: Vec<V6<S>>,
    /// Per body, scratch of ABA: articulated inertia and bias force, U = Iᴬ S, and
    /// (D = Sᵀ U, u = τ − Sᵀ pᴬ).
    pub(super) articulated: Vec<M6<S>>,
    pub(super) bias_force: Vec<V6<S>>,
    pub(super) u_col: Vec<V6<S>>,
    pub(super) pivot: Vec<(S, S)>,
}

impl Default for Data<f64> {
    fn default() -> Self {
        Self::empty(&0.0)
    }
}

/// Values per body that `save_placements` keeps: a rotation, an origin and a joint axis.
pub const PLACED: usize = 9 + 3 + 6;

/// A parent's entry p and its child's i in a per-body vector (p < i: every body comes after its
/// parent), to add the child's into the parent's without copying it first.
pub(super) fn parent_and_child<T>(v: &mut [T], p: usize, i: usize) -> (&mut T, &T) {
    let (head, tail) = v.split_at_mut(i);
    (&mut head[p], &tail[0])
}

fn fit<T: Clone>(v: &mut Vec<T>, len: usize, zero: &T) {
    v.resize(len, zero.clone());
}

impl<S: Scalar> Data<S> {
    /// A workspace sized for `model`, its values of the kind of `zero` (a batch column's
    /// length, a dual number's directions).
    pub fn like(model: &Model, zero: &S) -> Self {
        let mut d = Self::empty(zero);
        d.fit(model, zero);
        d
    }

    /// A workspace for one call at coordinates like `q`.
    pub fn for_state(model: &Model, q: &[S]) -> Self {
        Self::like(model, &q[0].lift(0.0))
    }

    fn empty(zero: &S) -> Self {
        Self {
            n: 0,
            rot: vec![],
            pos: vec![],
            s: vec![],
            v: vec![],
            d: vec![],
            a: vec![],
            a0: zeros(zero),
            rate: vec![],
            inertia: vec![],
            momentum: vec![],
            composite: vec![],
            force: vec![],
            mass: vec![],
            chol: vec![],
            bias: vec![],
            qdd: vec![],
            id_dq: vec![],
            id_dqd: vec![],
            alpha: vec![],
            variation: vec![],
            carried: vec![],
            reach_i: vec![],
            reach_b: vec![],
            articulated: vec![],
            bias_force: vec![],
            u_col: vec![],
            pivot: vec![],
        }
    }

    /// Sizes every vector for `model` (no allocation once they have been this long).
    fn fit(&mut self, model: &Model, zero: &S) {
        let (nb, n) = (model.bodies.len(), model.n);
        if (self.n, self.rot.len()) == (n, nb) {
            return;
        }
        self.n = n;
        let (z6, z66) = (zeros(zero), zeros_m6(zero));
        let z3: V3<S> = [zero.clone(), zero.clone(), zero.clone()];
        fit(&mut self.rot, nb, &[z3.clone(), z3.clone(), z3.clone()]);
        fit(&mut self.pos, nb, &z3);
        for v in [
            &mut self.s,
            &mut self.v,
            &mut self.d,
            &mut self.a,
            &mut self.momentum,
            &mut self.force,
            &mut self.alpha,
            &mut self.carried,
            &mut self.reach_i,
            &mut self.reach_b,
            &mut self.bias_force,
            &mut self.u_col,
        ] {
            fit(v, nb, &z6);
        }
        for m in [
            &mut self.inertia,
            &mut self.composite,
            &mut self.articulated,
        ] {
            fit(m, nb, &z66);
        }
        fit(&mut self.variation, nb, &Variation::zero(zero));
        fit(&mut self.rate, nb, zero);
        fit(&mut self.pivot, nb, &(zero.clone(), zero.clone()));
        for m in [
            &mut self.mass,
            &mut self.chol,
            &mut self.id_dq,
            &mut self.id_dqd,
        ] {
            fit(m, n * n, zero);
        }
        fit(&mut self.bias, n, zero);
        fit(&mut self.qdd, n, zero);
    }

    /// Placements, axes, velocities and inertias at (q, q̇), and the accelerations at q̈ = 0.
    pub fn kinematics(&mut self, model: &Model, q: &[S], qd: &[S]) {
        self.placements(model, q);
        self.motion(model, qd, true, None);
    }

    /// `kinematics` with the root at rest instead of accelerating at −g: what the terms
    /// without gravity (C q̇ alone) are computed from.
    pub fn kinematics_without_gravity(&mut self, model: &Model, q: &[S], qd: &[S]) {
        self.placements(model, q);
        self.motion(model, qd, false, None);
    }

    /// `kinematics` with the bodies' inertias given over the scalar in place of the model's
    /// (a URDF template's trainable values).
    pub fn kinematics_with(&mut self, model: &Model, q: &[S], qd: &[S], inertias: &[Inertial<S>]) {
        self.placements(model, q);
        self.motion(model, qd, true, Some(inertias));
    }

    /// Each body's placement and joint axis in the root frame: what depends on q alone (and
    /// holds the trigonometry).
    pub(super) fn placements(&mut self, model: &Model, q: &[S]) {
        let zero = q[0].lift(0.0);
        self.fit(model, &zero);
        for (i, body) in model.bodies.iter().enumerate() {
            let x = body.placement(q, &zero);
            let (e, p) = match body.parent {
                Some(k) => {
                    let (ek, pk) = (&self.rot[k], &self.pos[k]);
                    // E₀ = E E₀_parent, p = p_parent + E₀_parentᵀ r.
                    let mut p = pk.clone();
                    let e: M3<S> = std::array::from_fn(|r| {
                        std::array::from_fn(|c| {
                            x.e[r][0].clone() * ek[0][c].clone()
                                + x.e[r][1].clone() * ek[1][c].clone()
                                + x.e[r][2].clone() * ek[2][c].clone()
                        })
                    });
                    for (r, pr) in p.iter_mut().enumerate() {
                        for (ekc, xr) in ek.iter().zip(&x.r) {
                            *pr = pr.clone() + ekc[r].clone() * xr.clone();
                        }
                    }
                    (e, p)
                }
                None => (x.e, x.r),
            };
            self.s[i] = motion_to_root(&e, &p, &body.joint.subspace());
            (self.rot[i], self.pos[i]) = (e, p);
        }
    }

    /// After `placements`: velocities, d, accelerations at q̈ = 0, root-frame inertias and
    /// momenta at q̇ (of the bodies' `given` inertias, else the model's).
    fn motion(&mut self, model: &Model, qd: &[S], gravity: bool, given: Option<&[Inertial<S>]>) {
        let zero = self.a0[0].lift(0.0);
        let g = if gravity { model.gravity } else { [0.0; 3] };
        self.a0 = [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]].map(|x| zero.lift(x));
        let rest = zeros(&zero);
        for (i, body) in model.bodies.iter().enumerate() {
            let (vp, ap) = match body.parent {
                Some(k) => (&self.v[k], &self.a[k]),
                None => (&rest, &self.a0),
            };
            let s = &self.s[i];
            let rate = body.drive.rate(qd);
            let d = cross(vp, s);
            self.v[i] = add_scaled(vp, &rate, s);
            self.a[i] = add_scaled(ap, &rate, &d);
            (self.d[i], self.rate[i]) = (d, rate);
            let (e, p, out) = (&self.rot[i], &self.pos[i], &mut self.inertia[i]);
            match given {
                Some(b) => inertia_to_root(e, p, &b[i], out),
                None => inertia_to_root(e, p, &body.inertia.lift(&zero), out),
            }
            self.momentum[i] = apply(&self.inertia[i], &self.v[i]);
        }
    }

    /// Each body's force I a + v ×* I v at the current accelerations, summed over its subtree.
    fn subtree_forces(&mut self, model: &Model) {
        for i in 0..model.bodies.len() {
            let ia = apply(&self.inertia[i], &self.a[i]);
            self.force[i] = add(&ia, &cross_force(&self.v[i], &self.momentum[i]));
        }
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                self.force[p] = add(&self.force[p], &self.force[i]);
            }
        }
    }

    /// After `kinematics`: composite inertias and M by CRBA over the coordinates
    /// (M_kj = S_k · Iᶜ_k S_j for j on k's path to the root).
    pub fn mass(&mut self, model: &Model) {
        self.composite.clone_from_slice(&self.inertia);
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                let (parent, child) = parent_and_child(&mut self.composite, p, i);
                add_assign(parent, child);
            }
        }
        let n = self.n;
        let zero = self.a0[0].lift(0.0);
        self.mass.fill(zero.clone());
        for (k, body) in model.bodies.iter().enumerate() {
            let (ck, gk) = (body.drive.coordinate, body.drive.multiplier);
            let r = apply(&self.composite[k], &self.s[k]);
            let mut j = Some(k);
            while let Some(jj) = j {
                let other = &model.bodies[jj].drive;
                let h = dot(&r, &self.s[jj]).scale(gk * other.multiplier);
                let (a, b) = (ck, other.coordinate);
                if jj != k {
                    // Symmetric: (b, a) is the mirror entry (twice on the diagonal when two
                    // joints share a coordinate).
                    self.mass[b * n + a] = self.mass[b * n + a].clone() + h.clone();
                }
                self.mass[a * n + b] = self.mass[a * n + b].clone() + h;
                j = model.bodies[jj].parent;
            }
        }
        if let Some(armature) = &model.armature {
            for (c, &r) in armature.iter().enumerate() {
                self.mass[c * n + c] = self.mass[c * n + c].clone() + zero.lift(r);
            }
        }
    }

    /// Sᵀ F over the coordinates into `bias`: τ = ID at the accelerations the bodies have
    /// (C q̇ + g after `kinematics`, all of ID after `accelerations`).
    pub fn torques(&mut self, model: &Model) {
        self.subtree_forces(model);
        let zero = self.a0[0].lift(0.0);
        self.bias.fill(zero);
        for (k, body) in model.bodies.iter().enumerate() {
            let (ck, gk) = (body.drive.coordinate, body.drive.multiplier);
            let t = dot(&self.s[k], &self.force[k]).scale(gk);
            self.bias[ck] = self.bias[ck].clone() + t;
        }
    }

    /// With q̈ set: τ = ID(q, q̇, q̈) into `bias`, RNEA's second pass with the armatures'
    /// a∘q̈ (which no body carries).
    pub fn inverse_torques(&mut self, model: &Model) {
        self.accelerations(model);
        self.torques(model);
        if let Some(armature) = &model.armature {
            for ((t, &r), a) in self.bias.iter_mut().zip(armature).zip(&self.qdd) {
                *t = t.clone() + a.scale(r);
            }
        }
    }

    /// `mass`, and C q̇ + g by RNEA at q̈ = 0 over the coordinates.
    pub fn mass_and_bias(&mut self, model: &Model) {
        self.mass(model);
        self.torques(model);
    }

    /// The Cholesky factor of M (NaN where M is not positive definite).
    pub fn factor(&mut self) {
        cholesky::factor(&self.mass, self.n, &mut self.chol);
    }

    /// x ← M⁻¹ x for an n×cols row-major block (each column a right-hand side).
    pub fn solve(&self, x: &mut [S], cols: usize) {
        cholesky::solve(&self.chol, self.n, x, cols);
    }

    /// With q̈ set: the bodies' accelerations and subtree forces at it.
    pub fn accelerations(&mut self, model: &Model) {
        for (i, body) in model.bodies.iter().enumerate() {
            let ap = body.parent.map_or(&self.a0, |p| &self.a[p]);
            let acc = body.drive.rate(&self.qdd);
            let a = add_scaled(ap, &self.rate[i], &self.d[i]);
            self.a[i] = add_scaled(&a, &acc, &self.s[i]);
        }
        self.subtree_forces(model);
    }

    /// q̈ = FD(q, q̇, τ) = M⁻¹ (τ − C q̇ − g) by CRBA and Cholesky, leaving M, its factor, the
    /// bias and the state at q̈ behind (what the derivatives read).
    pub fn crba_forward(&mut self, model: &Model, q: &[S], qd: &[S], tau: &[S]) {
        self.kinematics(model, q, qd);
        self.mass_and_bias(model);
        self.factor();
        for ((a, t), b) in self.qdd.iter_mut().zip(tau).zip(&self.bias) {
            *a = t.clone() - b.clone();
        }
        let mut qdd = std::mem::take(&mut self.qdd);
        self.solve(&mut qdd, 1);
        self.qdd = qdd;
        self.accelerations(model);
    }

    /// q̈ = FD(q, q̇, τ) alone: the articulated-body algorithm without mimic joints, else
    /// `crba_forward`; the bodies' accelerations at q̈ are left behind.
    pub fn forward_dynamics(&mut self, model: &Model, q: &[S], qd: &[S], tau: &[S]) {
        if model.mimic {
            return self.crba_forward(model, q, qd, tau);
        }
        self.kinematics(model, q, qd);
        self.aba(model, tau);
    }
}

impl Data<f64> {
    pub fn new(model: &Model) -> Self {
        Self::like(model, &0.0)
    }

    /// Appends what `placements` computed (`PLACED` values per body) to `out`: a pass over
    /// the same q later (training's backward pass) restores it instead of recomputing it.
    pub fn save_placements(&self, out: &mut Vec<f64>) {
        for ((e, p), s) in self.rot.iter().zip(&self.pos).zip(&self.s) {
            out.extend(e.iter().flatten().chain(p).chain(s));
        }
    }

    /// `kinematics` at (q, q̇) with q's placements from `save_placements` (`saved` holds
    /// `PLACED` values per body of `model`).
    pub fn kinematics_from(&mut self, model: &Model, saved: &[f64], qd: &[f64]) {
        self.fit(model, &0.0);
        let bodies = self.rot.iter_mut().zip(&mut self.pos).zip(&mut self.s);
        for (((e, p), s), x) in bodies.zip(saved.chunks_exact(PLACED)) {
            for (r, row) in e.iter_mut().enumerate() {
                row.copy_from_slice(&x[3 * r..3 * r + 3]);
            }
            p.copy_from_slice(&x[9..12]);
            s.copy_from_slice(&x[12..]);
        }
        self.motion(model, qd, true, None);
    }
}

//! The workspace of the f64 algorithms (docs/robots.md#the-data-workspace), as Pinocchio's
//! `Data`: every per-configuration quantity of one state, computed once in the root frame and
//! shared by CRBA, RNEA, forward dynamics, the derivatives of RNEA and the adjoint. Its
//! vectors only grow, so a workspace reused across calls (one per thread: [`with_data`])
//! allocates nothing after its first.
//!
//! In the root frame a body's joint axis S, velocity v and acceleration a (the root's −g, so
//! gravity needs no term of its own) compose by sums down the tree, v = v_parent + S θ̇ and
//! a = a_parent + S θ̈ + d θ̇ with d = v_parent × S, and every body's force f = I a + v ×* I v
//! (I in the root frame) adds up the tree without transforms. That is what makes the analytic
//! derivatives of RNEA (`derivatives`) a sum of dot products.

use std::cell::RefCell;

use super::Model;
use super::spatial::six::{
    M6, V6, Variation, ZERO6, add, add_assign, add_scaled, apply, cross, cross_force, dot,
    inertia_to_root, motion_to_root,
};
use super::spatial::{M3, V3};

/// Quantities at one state; see the module comment. Body-indexed vectors follow
/// `Model::bodies`, matrices over the coordinates are n×n row-major.
#[derive(Debug, Default, Clone)]
pub struct Data {
    n: usize,
    /// Root axes to the body's, and the body's origin in the root frame.
    pub(super) rot: Vec<M3<f64>>,
    pub(super) pos: Vec<V3<f64>>,
    /// Joint axis, velocity, d = v_parent × S, acceleration: all in the root frame.
    pub(super) s: Vec<V6>,
    pub(super) v: Vec<V6>,
    pub(super) d: Vec<V6>,
    pub(super) a: Vec<V6>,
    /// Joint velocities θ̇ (a mimic joint's from its coordinate's).
    pub(super) rate: Vec<f64>,
    /// The body's inertia in the root frame, its momentum I v, and the composite inertia of
    /// the subtree it carries.
    pub(super) inertia: Vec<M6>,
    pub(super) momentum: Vec<V6>,
    pub(super) composite: Vec<M6>,
    /// After `accelerations`: the force of each body's subtree.
    pub(super) force: Vec<V6>,
    /// M(q), its Cholesky factor (lower), C q̇ + g, and q̈.
    pub mass: Vec<f64>,
    pub(super) chol: Vec<f64>,
    pub bias: Vec<f64>,
    pub qdd: Vec<f64>,
    /// ∂ID/∂q and ∂ID/∂q̇ (row i is τᵢ's), after `id_derivatives`.
    pub id_dq: Vec<f64>,
    pub id_dqd: Vec<f64>,
    /// Per body, scratch of `id_derivatives`: α = a_parent × S + v_parent × d, and the composite
    /// variation B of the body force in v.
    pub(super) alpha: Vec<V6>,
    pub(super) variation: Vec<Variation>,
    /// Per body, scratch of the adjoint: w = Σ S λ over its path from the root, and the sums
    /// over its subtree of λ Iᶜ S and λ Bᶜᵀ S.
    pub(super) carried: Vec<V6>,
    pub(super) reach_i: Vec<V6>,
    pub(super) reach_b: Vec<V6>,
    /// Per body, scratch of ABA: articulated inertia and bias force, U = Iᴬ S, and
    /// (D = Sᵀ U, u = τ − Sᵀ pᴬ).
    pub(super) articulated: Vec<M6>,
    pub(super) bias_force: Vec<V6>,
    pub(super) u_col: Vec<V6>,
    pub(super) pivot: Vec<(f64, f64)>,
}

thread_local! {
    static WORKSPACE: RefCell<Data> = RefCell::new(Data::default());
}

/// `f` with this thread's workspace, grown to the largest model the thread has served (a fresh
/// one if the thread's is in use further up the stack).
pub fn with_data<R>(f: impl FnOnce(&mut Data) -> R) -> R {
    WORKSPACE.with(|d| match d.try_borrow_mut() {
        Ok(mut d) => f(&mut d),
        Err(_) => f(&mut Data::default()),
    })
}

/// Values per body that `save_placements` keeps: a rotation, an origin and a joint axis.
pub const PLACED: usize = 9 + 3 + 6;

fn fit<T: Clone + Default>(v: &mut Vec<T>, len: usize) {
    v.resize(len, T::default());
}

impl Data {
    pub fn new(model: &Model) -> Self {
        let mut d = Self::default();
        d.fit(model);
        d
    }

    /// Sizes every vector for `model` (no allocation once they have been this long).
    fn fit(&mut self, model: &Model) {
        let (nb, n) = (model.bodies.len(), model.n);
        if (self.n, self.rot.len()) == (n, nb) {
            return;
        }
        self.n = n;
        fit(&mut self.rot, nb);
        fit(&mut self.pos, nb);
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
            fit(v, nb);
        }
        for m in [
            &mut self.inertia,
            &mut self.composite,
            &mut self.articulated,
        ] {
            fit(m, nb);
        }
        fit(&mut self.variation, nb);
        fit(&mut self.rate, nb);
        fit(&mut self.pivot, nb);
        for m in [
            &mut self.mass,
            &mut self.chol,
            &mut self.id_dq,
            &mut self.id_dqd,
        ] {
            fit(m, n * n);
        }
        fit(&mut self.bias, n);
        fit(&mut self.qdd, n);
    }

    /// Placements, axes, velocities and inertias at (q, q̇), and the accelerations at q̈ = 0.
    pub fn kinematics(&mut self, model: &Model, q: &[f64], qd: &[f64]) {
        self.placements(model, q);
        self.motion(model, qd);
    }

    /// Each body's placement and joint axis in the root frame: what depends on q alone (and
    /// holds the trigonometry).
    fn placements(&mut self, model: &Model, q: &[f64]) {
        self.fit(model);
        for (i, body) in model.bodies.iter().enumerate() {
            let x = body.placement(q, &0.0);
            let (e, p) = match body.parent {
                Some(k) => {
                    let (ek, pk) = (&self.rot[k], &self.pos[k]);
                    // E₀ = E E₀_parent, p = p_parent + E₀_parentᵀ r.
                    let (mut e, mut p) = ([[0.0; 3]; 3], *pk);
                    for r in 0..3 {
                        for c in 0..3 {
                            e[r][c] =
                                x.e[r][0] * ek[0][c] + x.e[r][1] * ek[1][c] + x.e[r][2] * ek[2][c];
                            p[r] += ek[c][r] * x.r[c];
                        }
                    }
                    (e, p)
                }
                None => (x.e, x.r),
            };
            self.s[i] = motion_to_root(&e, &p, &body.joint.motion(&1.0, &0.0));
            (self.rot[i], self.pos[i]) = (e, p);
        }
    }

    /// After `placements`: velocities, d, accelerations at q̈ = 0, root-frame inertias and
    /// momenta at q̇.
    fn motion(&mut self, model: &Model, qd: &[f64]) {
        let g = model.gravity;
        let a0 = [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]];
        for (i, body) in model.bodies.iter().enumerate() {
            let (vp, ap) = body.parent.map_or((ZERO6, a0), |k| (self.v[k], self.a[k]));
            let s = &self.s[i];
            let rate = body.drive.rate(qd);
            let d = cross(&vp, s);
            self.v[i] = add_scaled(&vp, rate, s);
            self.a[i] = add_scaled(&ap, rate, &d);
            self.inertia[i] = inertia_to_root(&self.rot[i], &self.pos[i], &body.inertia);
            self.momentum[i] = apply(&self.inertia[i], &self.v[i]);
            self.d[i] = d;
            self.rate[i] = rate;
        }
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
        self.fit(model);
        let bodies = self.rot.iter_mut().zip(&mut self.pos).zip(&mut self.s);
        for (((e, p), s), x) in bodies.zip(saved.chunks_exact(PLACED)) {
            for (r, row) in e.iter_mut().enumerate() {
                row.copy_from_slice(&x[3 * r..3 * r + 3]);
            }
            p.copy_from_slice(&x[9..12]);
            s.copy_from_slice(&x[12..]);
        }
        self.motion(model, qd);
    }

    /// Each body's force I a + v ×* I v at the current accelerations, summed over its subtree.
    fn subtree_forces(&mut self, model: &Model) {
        for i in 0..model.bodies.len() {
            let ia = apply(&self.inertia[i], &self.a[i]);
            self.force[i] = add(&ia, &cross_force(&self.v[i], &self.momentum[i]));
        }
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                let f = self.force[i];
                self.force[p] = add(&self.force[p], &f);
            }
        }
    }

    /// After `kinematics`: composite inertias and M by CRBA over the coordinates
    /// (M_kj = S_k · Iᶜ_k S_j for j on k's path to the root).
    pub fn mass(&mut self, model: &Model) {
        self.composite.clone_from_slice(&self.inertia);
        for (i, body) in model.bodies.iter().enumerate().rev() {
            if let Some(p) = body.parent {
                let c = self.composite[i];
                add_assign(&mut self.composite[p], &c);
            }
        }
        let n = self.n;
        self.mass.fill(0.0);
        for (k, body) in model.bodies.iter().enumerate() {
            let (ck, gk) = (body.drive.coordinate, body.drive.multiplier);
            let r = apply(&self.composite[k], &self.s[k]);
            let mut j = Some(k);
            while let Some(jj) = j {
                let other = &model.bodies[jj].drive;
                let h = gk * other.multiplier * dot(&r, &self.s[jj]);
                let (a, b) = (ck, other.coordinate);
                if jj != k {
                    // Symmetric: (b, a) is the mirror entry (twice on the diagonal when two
                    // joints share a coordinate).
                    self.mass[b * n + a] += h;
                }
                self.mass[a * n + b] += h;
                j = model.bodies[jj].parent;
            }
        }
    }

    /// `mass`, and C q̇ + g by RNEA at q̈ = 0 over the coordinates.
    pub fn mass_and_bias(&mut self, model: &Model) {
        self.mass(model);
        self.subtree_forces(model);
        self.bias.fill(0.0);
        for (k, body) in model.bodies.iter().enumerate() {
            let (ck, gk) = (body.drive.coordinate, body.drive.multiplier);
            self.bias[ck] += gk * dot(&self.s[k], &self.force[k]);
        }
    }

    /// The Cholesky factor of M (NaN where M is not positive definite, as `cholesky` gives).
    pub fn factor(&mut self) {
        let n = self.n;
        for i in 0..n {
            for j in 0..=i {
                let mut s = self.mass[i * n + j];
                for k in 0..j {
                    s -= self.chol[i * n + k] * self.chol[j * n + k];
                }
                self.chol[i * n + j] = if i == j {
                    s.sqrt()
                } else {
                    s / self.chol[j * n + j]
                };
            }
        }
    }

    /// x ← M⁻¹ x for an n×cols row-major block (each column a right-hand side).
    pub fn solve(&self, x: &mut [f64], cols: usize) {
        let (n, l) = (self.n, &self.chol);
        for i in 0..n {
            let (done, rest) = x.split_at_mut(i * cols);
            let row = &mut rest[..cols];
            for (k, prev) in done.chunks_exact(cols).enumerate() {
                let lik = l[i * n + k];
                row.iter_mut().zip(prev).for_each(|(r, p)| *r -= lik * p);
            }
            let d = l[i * n + i];
            row.iter_mut().for_each(|r| *r /= d);
        }
        for i in (0..n).rev() {
            let (head, after) = x.split_at_mut((i + 1) * cols);
            let row = &mut head[i * cols..];
            for (k, next) in after.chunks_exact(cols).enumerate() {
                let lki = l[(i + 1 + k) * n + i];
                row.iter_mut().zip(next).for_each(|(r, p)| *r -= lki * p);
            }
            let d = l[i * n + i];
            row.iter_mut().for_each(|r| *r /= d);
        }
    }

    /// With q̈ set: the bodies' accelerations and subtree forces at it.
    pub fn accelerations(&mut self, model: &Model) {
        let g = model.gravity;
        let a0 = [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]];
        for (i, body) in model.bodies.iter().enumerate() {
            let ap = body.parent.map_or(a0, |p| self.a[p]);
            let acc = body.drive.rate(&self.qdd);
            let a = add_scaled(&ap, self.rate[i], &self.d[i]);
            self.a[i] = add_scaled(&a, acc, &self.s[i]);
        }
        self.subtree_forces(model);
    }

    /// q̈ = FD(q, q̇, τ) = M⁻¹ (τ − C q̇ − g) by CRBA and Cholesky, leaving M, its factor, the
    /// bias and the state at q̈ behind (what the derivatives read).
    pub fn crba_forward(&mut self, model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) {
        self.kinematics(model, q, qd);
        self.mass_and_bias(model);
        self.factor();
        for ((a, t), b) in self.qdd.iter_mut().zip(tau).zip(&self.bias) {
            *a = t - b;
        }
        let mut qdd = std::mem::take(&mut self.qdd);
        self.solve(&mut qdd, 1);
        self.qdd = qdd;
        self.accelerations(model);
    }

    /// q̈ = FD(q, q̇, τ) alone: the articulated-body algorithm without mimic joints, else
    /// `crba_forward`; the bodies' accelerations at q̈ are left behind.
    pub fn forward_dynamics(&mut self, model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) {
        if model.mimic {
            return self.crba_forward(model, q, qd, tau);
        }
        self.kinematics(model, q, qd);
        self.aba(model, tau);
    }
}

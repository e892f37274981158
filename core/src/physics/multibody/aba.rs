//! Forward dynamics q̈ = FD(q, q̇, τ): the articulated-body algorithm (Featherstone 2008,
//! Table 7.1) for a tree without mimic joints, and M q̈ = τ − (C q̇ + g) by CRBA, RNEA and a
//! Cholesky solve for any tree (a mimic joint is not a degree of freedom of its own, which
//! ABA's per-joint recursion assumes).

use super::Model;
use super::data::Data;
use super::rnea::{bias, crba};
use super::spatial::six::{add, add_assign, add_scaled, apply, cross_force, dot};
use super::spatial::{Force, Inertia, Motion, Xform};
use crate::physics::dynamics::{cholesky, solve_llt};
use crate::physics::scalar::Scalar;

/// q̈ by the articulated-body algorithm; τ on the coordinates. Panics on a tree with mimic
/// joints (use `forward_dynamics`).
pub fn aba<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    assert!(!model.mimic, "ABA takes a tree without mimic joints");
    let zero = q[0].lift(0.0);
    let nb = model.bodies.len();
    let mut xs: Vec<Xform<S>> = Vec::with_capacity(nb);
    let mut vs: Vec<Motion<S>> = Vec::with_capacity(nb);
    // Velocity-product accelerations c = v × S q̇, articulated inertias and bias forces.
    let mut cs: Vec<Motion<S>> = Vec::with_capacity(nb);
    let mut ia: Vec<Inertia<S>> = Vec::with_capacity(nb);
    let mut pa: Vec<Force<S>> = Vec::with_capacity(nb);
    for j in &model.bodies {
        let x = j.placement(q, &zero);
        let vj = j.joint_motion(qd, &zero);
        let v = match j.parent {
            Some(p) => x.motion(&vs[p]).plus(&vj),
            None => vj.clone(),
        };
        cs.push(v.cross(&vj));
        pa.push(v.cross_force(&j.inertia.apply_const(&v, &zero)));
        ia.push(j.inertia.lift(&zero));
        xs.push(x);
        vs.push(v);
    }
    // U = Iᴬ S, D = Sᵀ U, u = τ − Sᵀ pᴬ, from the leaves in.
    let mut us: Vec<(Force<S>, S, S)> = Vec::with_capacity(nb);
    for i in (0..nb).rev() {
        let j = &model.bodies[i];
        let u_col = j.inertia_column(&ia[i], &zero);
        let d = j.project(&u_col, &zero);
        let u = tau[j.drive.coordinate].clone() - j.project(&pa[i], &zero);
        if let Some(p) = j.parent {
            let i_a = ia[i].minus_outer(&u_col, &d);
            let ud = u.clone() / d.clone();
            let p_a = pa[i].plus(&i_a.apply(&cs[i])).plus(&Force {
                n: u_col.n.clone().map(|x| x * ud.clone()),
                f: u_col.f.clone().map(|x| x * ud.clone()),
            });
            let up = xs[i].inertia_to_parent(&i_a);
            ia[p].add_assign(&up);
            let up = xs[i].force_to_parent(&p_a);
            pa[p] = pa[p].plus(&up);
        }
        us.push((u_col, d, u));
    }
    us.reverse();
    // Accelerations from the root out; the base accelerates at −g.
    let mut a0 = Motion::zero(&zero);
    a0.v = model.gravity.map(|g| zero.lift(-g));
    let mut accs: Vec<Motion<S>> = Vec::with_capacity(nb);
    let mut qdd: Vec<S> = vec![zero.clone(); model.n];
    for (i, j) in model.bodies.iter().enumerate() {
        let a = xs[i]
            .motion(match j.parent {
                Some(p) => &accs[p],
                None => &a0,
            })
            .plus(&cs[i]);
        let (u_col, d, u) = &us[i];
        let x = (u.clone() - a.dot(u_col)) / d.clone();
        accs.push(a.plus(&j.joint.motion(&x, &zero)));
        qdd[j.drive.coordinate] = x;
    }
    qdd
}

/// q̈ from M(q) q̈ = τ − C(q, q̇) q̇ − g(q): CRBA, RNEA and a Cholesky solve (any tree).
pub fn crba_forward<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    let m = crba(model, q);
    let rhs = tau
        .iter()
        .zip(bias(model, q, qd))
        .map(|(t, b)| t.clone() - b)
        .collect();
    solve_llt(&cholesky(&m), rhs)
}

/// q̈: ABA without mimic joints, else CRBA and Cholesky.
pub fn forward_dynamics<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    if model.mimic {
        crba_forward(model, q, qd, tau)
    } else {
        aba(model, q, qd, tau)
    }
}

impl Data {
    /// q̈ by the articulated-body algorithm in the root frame after `kinematics` (no mimic
    /// joints): the same recursion as `aba` with every transform the identity, since the
    /// workspace's inertias, velocities and axes are all in one frame.
    pub(super) fn aba(&mut self, model: &Model, tau: &[f64]) {
        for i in 0..model.bodies.len() {
            self.articulated[i] = self.inertia[i];
            self.bias_force[i] = cross_force(&self.v[i], &self.momentum[i]);
        }
        for (i, body) in model.bodies.iter().enumerate().rev() {
            let s = &self.s[i];
            let u_col = apply(&self.articulated[i], s);
            let d = dot(s, &u_col);
            let u = tau[body.drive.coordinate] - dot(s, &self.bias_force[i]);
            (self.u_col[i], self.pivot[i]) = (u_col, (d, u));
            if let Some(p) = body.parent {
                let ia = &mut self.articulated[i];
                for (row, &ur) in ia.iter_mut().zip(&u_col) {
                    let k = ur / d;
                    row.iter_mut().zip(&u_col).for_each(|(x, &uc)| *x -= k * uc);
                }
                let c = self.d[i].map(|x| x * self.rate[i]);
                let pa = add_scaled(&add(&self.bias_force[i], &apply(ia, &c)), u / d, &u_col);
                let ia = self.articulated[i];
                add_assign(&mut self.articulated[p], &ia);
                self.bias_force[p] = add(&self.bias_force[p], &pa);
            }
        }
        let g = model.gravity;
        let a0 = [0.0, 0.0, 0.0, -g[0], -g[1], -g[2]];
        for (i, body) in model.bodies.iter().enumerate() {
            let ap = body.parent.map_or(a0, |p| self.a[p]);
            let a = add_scaled(&ap, self.rate[i], &self.d[i]);
            let (d, u) = self.pivot[i];
            let x = (u - dot(&a, &self.u_col[i])) / d;
            self.a[i] = add_scaled(&a, x, &self.s[i]);
            self.qdd[body.drive.coordinate] = x;
        }
    }
}

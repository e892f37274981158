//! The recursive Newton–Euler algorithm (Featherstone 2008, Table 5.1) and the composite
//! rigid-body algorithm (Table 6.2), over the coordinates (mimic joints contracted with G).

use super::Model;
use super::spatial::{Force, Inertia, Motion, Xform};
use crate::physics::scalar::Scalar;

/// Joint torques contracted onto the coordinates: τ_q = Gᵀ τ_joints.
fn contract<S: Scalar>(model: &Model, tau: Vec<S>, zero: &S) -> Vec<S> {
    let mut out: Vec<Option<S>> = vec![None; model.n];
    for (j, t) in model.bodies.iter().zip(tau) {
        let t = if j.drive.multiplier != 1.0 {
            t.scale(j.drive.multiplier)
        } else {
            t
        };
        let c = &mut out[j.drive.coordinate];
        *c = Some(match c.take() {
            Some(s) => s + t,
            None => t,
        });
    }
    out.into_iter()
        .map(|t| t.unwrap_or_else(|| zero.clone()))
        .collect()
}

/// τ = M(q) q̈ + C(q, q̇) q̇ + g(q), with `None` for a zero q̇ or q̈ and `with_gravity` false
/// for a robot without gravity (so C q̇ comes out directly).
pub fn rnea<S: Scalar>(
    model: &Model,
    q: &[S],
    qd: Option<&[S]>,
    qdd: Option<&[S]>,
    with_gravity: bool,
) -> Vec<S> {
    let zero = q[0].lift(0.0);
    let nb = model.bodies.len();
    let mut xs: Vec<Xform<S>> = Vec::with_capacity(nb);
    let mut vs: Vec<Motion<S>> = Vec::with_capacity(if qd.is_some() { nb } else { 0 });
    let mut accs: Vec<Motion<S>> = Vec::with_capacity(nb);
    let mut fs: Vec<Force<S>> = Vec::with_capacity(nb);
    // The base accelerates upwards at −g instead of gravity acting on every body.
    let mut a0 = Motion::zero(&zero);
    if with_gravity {
        a0.v = model.gravity.map(|g| zero.lift(-g));
    }
    for (i, j) in model.bodies.iter().enumerate() {
        let x = j.placement(q, &zero);
        let mut a = x.motion(match j.parent {
            Some(p) => &accs[p],
            None => &a0,
        });
        if let Some(qdd) = qdd {
            a = a.plus(&j.joint_motion(qdd, &zero));
        }
        let f = if let Some(qd) = qd {
            let vj = j.joint_motion(qd, &zero);
            let v = match j.parent {
                Some(p) => x.motion(&vs[p]).plus(&vj),
                None => vj.clone(),
            };
            a = a.plus(&v.cross(&vj));
            let f = j.inertia.apply_const(&a, &zero);
            let f = f.plus(&v.cross_force(&j.inertia.apply_const(&v, &zero)));
            vs.push(v);
            f
        } else {
            j.inertia.apply_const(&a, &zero)
        };
        debug_assert_eq!(xs.len(), i);
        xs.push(x);
        accs.push(a);
        fs.push(f);
    }
    let mut tau: Vec<S> = vec![zero.clone(); nb];
    for i in (0..nb).rev() {
        let j = &model.bodies[i];
        tau[i] = j.project(&fs[i], &zero);
        if let Some(p) = j.parent {
            let up = xs[i].force_to_parent(&fs[i]);
            fs[p] = fs[p].plus(&up);
        }
    }
    contract(model, tau, &zero)
}

/// τ = ID(q, q̇, q̈) with gravity.
pub fn inverse_dynamics<S: Scalar>(model: &Model, q: &[S], qd: &[S], qdd: &[S]) -> Vec<S> {
    rnea(model, q, Some(qd), Some(qdd), true)
}

/// g(q) = ID(q, 0, 0) = ∂V/∂q.
pub fn gravity_torques<S: Scalar>(model: &Model, q: &[S]) -> Vec<S> {
    rnea(model, q, None, None, true)
}

/// C(q, q̇) q̇ = ID(q, q̇, 0) without gravity.
pub fn coriolis<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> Vec<S> {
    rnea(model, q, Some(qd), None, false)
}

/// C(q, q̇) q̇ + g(q) = ID(q, q̇, 0).
pub fn bias<S: Scalar>(model: &Model, q: &[S], qd: &[S]) -> Vec<S> {
    rnea(model, q, Some(qd), None, true)
}

/// M(q) over the coordinates by the composite rigid-body algorithm: each body's composite
/// inertia Iᶜ (itself and everything it carries), then H_ij = S_jᵀ X Iᶜ_i S_i for j on i's path
/// to the root, contracted M = Gᵀ H G (a mimic joint's multiplier on each side).
pub fn crba<S: Scalar>(model: &Model, q: &[S]) -> Vec<Vec<S>> {
    let zero = q[0].lift(0.0);
    let nb = model.bodies.len();
    let xs: Vec<Xform<S>> = (model.bodies.iter())
        .map(|j| j.placement(q, &zero))
        .collect();
    let mut ic: Vec<Inertia<S>> = (model.bodies.iter())
        .map(|j| j.inertia.lift(&zero))
        .collect();
    for i in (0..nb).rev() {
        if let Some(p) = model.bodies[i].parent {
            let up = xs[i].inertia_to_parent(&ic[i]);
            ic[p].add_assign(&up);
        }
    }
    let mut m: Vec<Vec<S>> = vec![vec![zero.clone(); model.n]; model.n];
    let mut put = |a: usize, b: usize, h: S| {
        let (ja, jb) = (&model.bodies[a], &model.bodies[b]);
        let g = ja.drive.multiplier * jb.drive.multiplier;
        let h = if g != 1.0 { h.scale(g) } else { h };
        let (ca, cb) = (ja.drive.coordinate, jb.drive.coordinate);
        if a != b {
            // H is symmetric: (b, a) lands on the mirror entry (twice on the diagonal when
            // two joints share a coordinate).
            m[cb][ca] = m[cb][ca].clone() + h.clone();
        }
        m[ca][cb] = m[ca][cb].clone() + h;
    };
    for (i, (ji, ici)) in model.bodies.iter().zip(&ic).enumerate() {
        let mut f = ji.inertia_column(ici, &zero);
        put(i, i, ji.project(&f, &zero));
        let mut k = i;
        while let Some(p) = model.bodies[k].parent {
            f = xs[k].force_to_parent(&f);
            k = p;
            put(i, k, model.bodies[k].project(&f, &zero));
        }
    }
    m
}

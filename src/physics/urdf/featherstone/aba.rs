//! Forward dynamics q̈ = FD(q, q̇, τ): the articulated-body algorithm (Featherstone 2008,
//! Table 7.1) for a tree without mimic joints, and M q̈ = τ − (C q̇ + g) by CRBA, RNEA and a
//! Cholesky solve for any tree (a mimic joint is not a degree of freedom of its own, which
//! ABA's per-joint recursion assumes). Over dual numbers either gives ∂q̈/∂q, ∂q̈/∂q̇ exactly.

use super::Model;
use super::rnea::{bias, crba};
use super::spatial::{Force, Inertia, Motion, Xform};
use crate::physics::dual::Dual;
use crate::physics::dynamics::{cholesky, solve_llt};
use crate::physics::jet::Jet;
use crate::physics::scalar::Scalar;

/// q̈ by the articulated-body algorithm; τ on the coordinates. Panics on a tree with mimic
/// joints (use `forward_dynamics`).
pub fn aba<S: Scalar>(model: &Model, q: &[S], qd: &[S], tau: &[S]) -> Vec<S> {
    assert!(!model.mimic, "ABA takes a tree without mimic joints");
    let zero = q[0].lift(0.0);
    let nb = model.joints.len();
    let mut xs: Vec<Xform<S>> = Vec::with_capacity(nb);
    let mut vs: Vec<Motion<S>> = Vec::with_capacity(nb);
    // Velocity-product accelerations c = v × S q̇, articulated inertias and bias forces.
    let mut cs: Vec<Motion<S>> = Vec::with_capacity(nb);
    let mut ia: Vec<Inertia<S>> = Vec::with_capacity(nb);
    let mut pa: Vec<Force<S>> = Vec::with_capacity(nb);
    for j in &model.joints {
        let x = j.xform(&j.value(q), &zero);
        let vj = j.motion(&j.rate(qd), &zero);
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
        let j = &model.joints[i];
        let u_col = j.inertia_column(&ia[i], &zero);
        let d = j.project(&u_col, &zero);
        let u = tau[j.coordinate].clone() - j.project(&pa[i], &zero);
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
    for (i, j) in model.joints.iter().enumerate() {
        let a = xs[i]
            .motion(match j.parent {
                Some(p) => &accs[p],
                None => &a0,
            })
            .plus(&cs[i]);
        let (u_col, d, u) = &us[i];
        let x = (u.clone() - a.dot(u_col)) / d.clone();
        accs.push(a.plus(&j.motion(&x, &zero)));
        qdd[j.coordinate] = x;
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

/// q̈ with ∂q̈/∂q and ∂q̈/∂q̇ (n×n each, row i is q̈ᵢ's gradient).
pub type Derivatives = (Vec<f64>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// q̈, ∂q̈/∂q and ∂q̈/∂q̇ by forward dynamics over dual numbers with 2n directions (q then q̇):
/// fixed-size `Jet`s up to n = 32 (no allocation; padded to 8, 16, 32 or 64 directions),
/// `Dual` beyond. ∂q̈/∂τ is M⁻¹.
pub fn forward_dynamics_derivatives(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    match 2 * q.len() {
        0..=8 => jet_derivatives::<8>(model, q, qd, tau),
        9..=16 => jet_derivatives::<16>(model, q, qd, tau),
        17..=32 => jet_derivatives::<32>(model, q, qd, tau),
        33..=64 => jet_derivatives::<64>(model, q, qd, tau),
        _ => dual_derivatives(model, q, qd, tau),
    }
}

fn jet_derivatives<const N: usize>(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
) -> Derivatives {
    let n = q.len();
    let qv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(q[k], k)).collect();
    let qdv: Vec<Jet<N>> = (0..n).map(|k| Jet::variable(qd[k], n + k)).collect();
    let tv: Vec<Jet<N>> = tau.iter().map(|&t| Jet::constant(t)).collect();
    let out = forward_dynamics(model, &qv, &qdv, &tv);
    (
        out.iter().map(|x| x.v).collect(),
        out.iter().map(|x| x.d[..n].to_vec()).collect(),
        out.iter().map(|x| x.d[n..2 * n].to_vec()).collect(),
    )
}

/// The same over `Dual` (sparse optional tangents; on the heap beyond eight directions).
pub fn dual_derivatives(model: &Model, q: &[f64], qd: &[f64], tau: &[f64]) -> Derivatives {
    let n = q.len();
    let qv: Vec<Dual<f64>> = (0..n)
        .map(|k| Dual::variable(q[k], k, 2 * n, 1.0))
        .collect();
    let qdv: Vec<Dual<f64>> = (0..n)
        .map(|k| Dual::variable(qd[k], n + k, 2 * n, 1.0))
        .collect();
    let tv: Vec<Dual<f64>> = tau.iter().map(|&t| Dual::constant(t)).collect();
    let out = forward_dynamics(model, &qv, &qdv, &tv);
    let d = |x: &Dual<f64>, k: usize| x.tangent(k).copied().unwrap_or(0.0);
    (
        out.iter().map(|x| x.v).collect(),
        out.iter()
            .map(|x| (0..n).map(|k| d(x, k)).collect())
            .collect(),
        out.iter()
            .map(|x| (0..n).map(|k| d(x, n + k)).collect())
            .collect(),
    )
}

//! A URDF template's parameters in their forms (docs/robots.md#physically-consistent-inertia):
//! the physical values a body's ten parameters and a joint's two are named by, and the map from
//! the raw values the optimiser moves (θ of each body's log-Cholesky pseudo-inertia) to them.

use std::borrow::Cow;

use super::inertia::{BodyInertia, Inertial};
use super::term::{C, Term, V};
use super::tree::Tree;
use crate::physics::params::{ParamInfo, Part};
use crate::physics::scalar::Scalar;

/// Parameters per body and per joint.
pub const PER_BODY: usize = 10;
pub(super) const PER_JOINT: usize = 2;

pub(super) const BODY_FIELDS: [&str; PER_BODY] = [
    "mass", "com_x", "com_y", "com_z", "ixx", "ixy", "ixz", "iyy", "iyz", "izz",
];

pub(super) fn params_of(tree: &Tree) -> Vec<ParamInfo> {
    use Part::{Forces, Mass, Potential};
    const MV: &[Part] = &[Mass, Potential];
    const M: &[Part] = &[Mass];
    const F: &[Part] = &[Forces];
    let mut out = vec![];
    for b in &tree.bodies {
        let i = &b.inertial;
        let c = i.com();
        let ic = i.inertia_at_com();
        let values = [
            i.mass, c[0], c[1], c[2], ic[0][0], ic[0][1], ic[0][2], ic[1][1], ic[1][2], ic[2][2],
        ];
        for (k, (field, v)) in BODY_FIELDS.iter().zip(values).enumerate() {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.{field}", b.link)),
                default: v,
                positive: k == 0,
                min: None,
                fixed: false,
                used_by: Cow::Borrowed(if k < 4 { MV } else { M }),
            });
        }
    }
    for b in &tree.bodies {
        for (field, v) in [("damping", b.damping), ("friction", b.friction)] {
            out.push(ParamInfo {
                name: Cow::Owned(format!("{}.{field}", b.joint)),
                default: v,
                positive: false,
                // Trained as themselves and kept ≥ 0 by projection: both often start at
                // exactly 0, where a logarithm cannot start and a square has no gradient.
                min: Some(0.0),
                fixed: false,
                used_by: Cow::Borrowed(F),
            });
        }
    }
    out
}

/// (m, c, Ī_c) as a body.
pub(super) fn inertial_of(v: &[f64]) -> Inertial {
    let ic = [[v[4], v[5], v[6]], [v[5], v[7], v[8]], [v[6], v[8], v[9]]];
    Inertial::from_com(v[0], [v[1], v[2], v[3]], ic)
}

/// θ = (α, d₁, d₂, d₃, s₁₂, s₁₃, s₂₃, t₁, t₂, t₃) → the raw order
/// (α, t₁, t₂, t₃, d₁, s₁₂, s₁₃, d₂, s₂₃, d₃).
pub(super) fn raw_order(t: &[f64; 10]) -> [f64; 10] {
    [t[0], t[7], t[8], t[9], t[1], t[4], t[5], t[2], t[6], t[3]]
}

/// One body's physical values from its raw ones: m = e^{2α}, c = t, and with the factor
/// R = [[e^d₁, s₁₂, s₁₃], [0, e^d₂, s₂₃], [0, 0, e^d₃]] the second moment about the centre of
/// mass Σ_c = m R Rᵀ, so Ī_c = tr(Σ_c) 𝟙 − Σ_c (inertia.rs: J = U Uᵀ).
pub(super) fn physical_of_theta<S: Scalar>(r: &[S]) -> [S; PER_BODY] {
    let [a, t1, t2, t3, d1, s12, s13, d2, s23, d3] =
        std::array::from_fn::<_, 10, _>(|k| r[k].clone());
    let m = (a.clone() + a).exp();
    let rows: [[Term<S>; 3]; 3] = [
        [V(d1.exp()), V(s12), V(s13)],
        [C(0.0), V(d2.exp()), V(s23)],
        [C(0.0), C(0.0), V(d3.exp())],
    ];
    let dot = |x: &[Term<S>; 3], y: &[Term<S>; 3]| {
        (x[0].clone() * y[0].clone())
            + (x[1].clone() * y[1].clone())
            + (x[2].clone() * y[2].clone())
    };
    let like = &m;
    let sigma = |i: usize, j: usize| m.clone() * dot(&rows[i], &rows[j]).value(like);
    let (s00, s11, s22) = (sigma(0, 0), sigma(1, 1), sigma(2, 2));
    let tr = s00.clone() + s11.clone() + s22.clone();
    [
        m.clone(),
        t1,
        t2,
        t3,
        tr.clone() - s00,
        -sigma(0, 1),
        -sigma(0, 2),
        tr.clone() - s11,
        -sigma(1, 2),
        tr - s22,
    ]
}

/// A body in the form the rigid-body terms take: h = m c, Ī_o = Ī_c + m(|c|² 𝟙 − c cᵀ).
pub(super) fn body_of_physical<S: Scalar>(v: &[S]) -> BodyInertia<S> {
    let m = v[0].clone();
    let c = [v[1].clone(), v[2].clone(), v[3].clone()];
    let ic = [
        [&v[4], &v[5], &v[6]],
        [&v[5], &v[7], &v[8]],
        [&v[6], &v[8], &v[9]],
    ];
    let c2 = c[0].square() + c[1].square() + c[2].square();
    let inertia = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let shift = if i == j {
                c2.clone() - c[i].square()
            } else {
                -(c[i].clone() * c[j].clone())
            };
            V(ic[i][j].clone() + m.clone() * shift)
        })
    });
    BodyInertia {
        h: c.clone().map(|ci| V(m.clone() * ci)),
        mass: V(m),
        inertia,
    }
}

/// One body's standard parameters as the recursive algorithms take them
/// (`featherstone::regressor`: m, m c, Ī about the link origin) from its physical values.
pub fn standard_of_physical<S: Scalar>(v: &[S]) -> [S; PER_BODY] {
    let b = body_of_physical(v);
    let like = &v[0];
    let [hx, hy, hz] = b.h;
    let i = |r: usize, c: usize| b.inertia[r][c].clone().value(like);
    [
        b.mass.value(like),
        hx.value(like),
        hy.value(like),
        hz.value(like),
        i(0, 0),
        i(0, 1),
        i(0, 2),
        i(1, 1),
        i(1, 2),
        i(2, 2),
    ]
}

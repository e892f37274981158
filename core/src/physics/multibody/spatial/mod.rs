//! Spatial algebra (Featherstone 2008, ch. 2) over any scalar, in fixed-size arrays: 3-vectors
//! and 3×3 matrices, a joint's transform (E, r), a body's inertia in each of its forms
//! (`inertia`, `raw`), and the 6-vectors and 6×6 matrices the algorithms run on in the root
//! frame (`six`: motions (ω, v), forces (n, f), inertias). Constants (axes, frames, inertias)
//! stay f64 and enter as `scale`, skipping zeros, so dual numbers pay only for what depends
//! on q.

mod inertia;
mod raw;
pub mod six;

pub use inertia::{
    Inertial, PER_BODY, STANDARD_NAMES, body_of_physical, of_physical, physical_values,
    standard_of_physical,
};
pub use raw::{MIN_MASS, MIN_SPREAD, body_inertia, physical_of_raw, raw_order};

use crate::physics::scalar::Scalar;

pub type V3<S> = [S; 3];
pub type M3<S> = [[S; 3]; 3];

pub fn cross<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [
        a[1].clone() * b[2].clone() - a[2].clone() * b[1].clone(),
        a[2].clone() * b[0].clone() - a[0].clone() * b[2].clone(),
        a[0].clone() * b[1].clone() - a[1].clone() * b[0].clone(),
    ]
}

pub fn dot<S: Scalar>(a: &V3<S>, b: &V3<S>) -> S {
    a[0].clone() * b[0].clone() + a[1].clone() * b[1].clone() + a[2].clone() * b[2].clone()
}

/// M x.
pub fn mv<S: Scalar>(m: &M3<S>, x: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| dot(&m[i], x))
}

pub fn mm<S: Scalar>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            a[i][0].clone() * b[0][j].clone()
                + a[i][1].clone() * b[1][j].clone()
                + a[i][2].clone() * b[2][j].clone()
        })
    })
}

/// Σ_k c_k x_k for constant c (zero terms skipped; c is never all zero where it is used).
pub fn cdot<S: Scalar>(c: &[f64; 3], x: &V3<S>, zero: &S) -> S {
    let mut acc: Option<S> = None;
    for (ck, xk) in c.iter().zip(x) {
        if *ck != 0.0 {
            let t = if *ck == 1.0 {
                xk.clone()
            } else {
                xk.scale(*ck)
            };
            acc = Some(match acc {
                None => t,
                Some(a) => a + t,
            });
        }
    }
    acc.unwrap_or_else(|| zero.clone())
}

/// c₀ + Σ cₖ xₖ with constants c (zero terms skipped).
pub fn affine<S: Scalar>(c0: f64, terms: [(&S, f64); 2], zero: &S) -> S {
    let mut acc: Option<S> = None;
    for (x, k) in terms {
        if k != 0.0 {
            let t = x.scale(k);
            acc = Some(match acc {
                None => t,
                Some(a) => a + t,
            });
        }
    }
    match acc {
        None => zero.lift(c0),
        Some(a) if c0 != 0.0 => a.shift(c0),
        Some(a) => a,
    }
}

pub fn lift3<S: Scalar>(c: &[f64; 3], zero: &S) -> V3<S> {
    c.map(|x| zero.lift(x))
}

pub(super) fn lift3x3<S: Scalar>(c: &[[f64; 3]; 3], zero: &S) -> M3<S> {
    c.map(|r| lift3(&r, zero))
}

/// A joint's parent-to-child transform at its value: X = [[E, 0], [−E r×, E]].
#[derive(Clone, Debug)]
pub struct Xform<S> {
    /// Parent axes to child axes.
    pub e: M3<S>,
    /// The child's origin in the parent frame.
    pub r: V3<S>,
}

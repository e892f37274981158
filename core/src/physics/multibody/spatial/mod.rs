//! Spatial algebra (Featherstone 2008, ch. 2) over any scalar, in fixed-size arrays: motion
//! vectors (ω, v), force vectors (n, f), Plücker transforms X = [[E, 0], [−E r×, E]] (parent
//! to child coordinates: E turns parent axes into the child's, r is the child's origin in the
//! parent frame) and symmetric 6×6 spatial inertias [[A, B], [Bᵀ, C]] (a rigid body about its
//! frame's origin: A = Ī, B = [h]×, C = m 𝟙). Constants (axes, frames, inertias) stay f64 and
//! enter as `scale`, skipping zeros, so dual numbers pay only for what depends on q.

mod inertia;
mod raw;
pub mod six;

pub use inertia::{
    BodyInertia, Inertia, Inertial, PER_BODY, STANDARD_NAMES, body_of_physical, of_physical,
    standard_of_physical,
};
pub use raw::{MIN_MASS, MIN_SPREAD, body_inertia, physical_of_raw, raw_order};

use crate::physics::scalar::Scalar;

pub type V3<S> = [S; 3];
pub type M3<S> = [[S; 3]; 3];

pub fn add<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| a[i].clone() + b[i].clone())
}

pub fn sub<S: Scalar>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| a[i].clone() - b[i].clone())
}

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

/// Mᵀ x.
pub fn mtv<S: Scalar>(m: &M3<S>, x: &V3<S>) -> V3<S> {
    std::array::from_fn(|i| {
        m[0][i].clone() * x[0].clone()
            + m[1][i].clone() * x[1].clone()
            + m[2][i].clone() * x[2].clone()
    })
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

/// Eᵀ M E.
fn congruence<S: Scalar>(e: &M3<S>, m: &M3<S>) -> M3<S> {
    let me = mm(m, e);
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            e[0][i].clone() * me[0][j].clone()
                + e[1][i].clone() * me[1][j].clone()
                + e[2][i].clone() * me[2][j].clone()
        })
    })
}

/// [r]× M: r crossed with each column.
fn cross_left<S: Scalar>(r: &V3<S>, m: &M3<S>) -> M3<S> {
    let cols: [V3<S>; 3] =
        std::array::from_fn(|j| cross(r, &[m[0][j].clone(), m[1][j].clone(), m[2][j].clone()]));
    std::array::from_fn(|i| std::array::from_fn(|j| cols[j][i].clone()))
}

/// M [r]×: each row crossed with r.
fn cross_right<S: Scalar>(m: &M3<S>, r: &V3<S>) -> M3<S> {
    std::array::from_fn(|i| cross(&m[i], r))
}

pub(super) fn mat_op<S: Scalar>(a: &M3<S>, b: &M3<S>, f: impl Fn(S, S) -> S) -> M3<S> {
    std::array::from_fn(|i| std::array::from_fn(|j| f(a[i][j].clone(), b[i][j].clone())))
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

/// c s for a constant vector c.
pub fn cscale<S: Scalar>(c: &[f64; 3], s: &S, zero: &S) -> V3<S> {
    std::array::from_fn(|k| match c[k] {
        0.0 => zero.clone(),
        1.0 => s.clone(),
        ck => s.scale(ck),
    })
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

/// A spatial motion vector: angular ω, linear v (of the point at the frame's origin).
#[derive(Clone, Debug)]
pub struct Motion<S> {
    pub w: V3<S>,
    pub v: V3<S>,
}

/// A spatial force vector: moment n (about the frame's origin), force f.
#[derive(Clone, Debug)]
pub struct Force<S> {
    pub n: V3<S>,
    pub f: V3<S>,
}

impl<S: Scalar> Motion<S> {
    pub fn zero(zero: &S) -> Self {
        let z = [zero.clone(), zero.clone(), zero.clone()];
        Self { w: z.clone(), v: z }
    }

    pub fn plus(&self, o: &Self) -> Self {
        Self {
            w: add(&self.w, &o.w),
            v: add(&self.v, &o.v),
        }
    }

    /// v × m (crm): the rate of change of m carried by a frame moving with v.
    pub fn cross(&self, m: &Motion<S>) -> Motion<S> {
        Motion {
            w: cross(&self.w, &m.w),
            v: add(&cross(&self.w, &m.v), &cross(&self.v, &m.w)),
        }
    }

    /// v ×* f (crf).
    pub fn cross_force(&self, f: &Force<S>) -> Force<S> {
        Force {
            n: add(&cross(&self.w, &f.n), &cross(&self.v, &f.f)),
            f: cross(&self.w, &f.f),
        }
    }

    /// The power m · f.
    pub fn dot(&self, f: &Force<S>) -> S {
        dot(&self.w, &f.n) + dot(&self.v, &f.f)
    }
}

impl<S: Scalar> Force<S> {
    pub fn plus(&self, o: &Self) -> Self {
        Self {
            n: add(&self.n, &o.n),
            f: add(&self.f, &o.f),
        }
    }

    /// c f.
    pub fn scale(&self, c: f64) -> Self {
        Self {
            n: self.n.clone().map(|x| x.scale(c)),
            f: self.f.clone().map(|x| x.scale(c)),
        }
    }
}

/// The parent-to-child Plücker transform of a joint at its value.
#[derive(Clone, Debug)]
pub struct Xform<S> {
    /// Parent axes to child axes.
    pub e: M3<S>,
    /// The child's origin in the parent frame.
    pub r: V3<S>,
}

impl<S: Scalar> Xform<S> {
    /// A motion in parent coordinates, in the child's: ω' = E ω, v' = E (v − r × ω).
    pub fn motion(&self, m: &Motion<S>) -> Motion<S> {
        Motion {
            w: mv(&self.e, &m.w),
            v: mv(&self.e, &sub(&m.v, &cross(&self.r, &m.w))),
        }
    }

    /// Xᵀ f (X* inverse): a force in child coordinates, in the parent's: f = Eᵀ f',
    /// n = Eᵀ n' + r × f.
    pub fn force_to_parent(&self, f: &Force<S>) -> Force<S> {
        let fp = mtv(&self.e, &f.f);
        Force {
            n: add(&mtv(&self.e, &f.n), &cross(&self.r, &fp)),
            f: fp,
        }
    }

    /// Xᵀ I X: an inertia in child coordinates, in the parent's. Rotated first (Eᵀ · E on
    /// each block), then moved by r: with T = [[𝟙, 0], [−r×, 𝟙]] and B' r× = T₀,
    /// A = A' − T₀ − T₀ᵀ − r× C' r×, B = B' + r× C', C = C'.
    pub fn inertia_to_parent(&self, i: &Inertia<S>) -> Inertia<S> {
        let (a, b, c) = (
            congruence(&self.e, &i.a),
            congruence(&self.e, &i.b),
            congruence(&self.e, &i.c),
        );
        let t0 = cross_right(&b, &self.r);
        let crc = cross_left(&self.r, &cross_right(&c, &self.r));
        let a = std::array::from_fn(|k| {
            std::array::from_fn(|l| {
                a[k][l].clone() - t0[k][l].clone() - t0[l][k].clone() - crc[k][l].clone()
            })
        });
        let b = mat_op(&b, &cross_left(&self.r, &c), |x, y| x + y);
        Inertia { a, b, c }
    }
}

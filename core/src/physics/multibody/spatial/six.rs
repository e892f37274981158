//! Spatial vectors and matrices as flat arrays over any [`Scalar`], for the algorithms that run
//! in the root frame (`Data`'s): a motion is (ω, v), a force (n, f), an inertia or any other
//! motion-to-force map a 6×6 matrix. Plain arrays and loops (no `array::from_fn`, which the
//! compiler left as an out-of-line call in the hot loops, 5 % of a training step's time) keep
//! the f64 instance as fast as hand-written f64 code: `clone` is a copy there. Each function
//! is `#[inline(always)]`: left to the compiler, the generic instances kept `apply` out of line
//! in the f64 passes (six calls per forward dynamics, 6 % of its instructions). The order of
//! every sum is fixed here, so each scalar type computes the same operations in the same
//! order and a batch column reproduces the single state bit for bit.

use super::{Inertial, M3, V3};
use crate::physics::scalar::Scalar;

pub type V6<S = f64> = [S; 6];
pub type M6<S = f64> = [[S; 6]; 6];

pub const ZERO6: V6 = [0.0; 6];

#[inline(always)]
pub fn zeros<S: Scalar>(zero: &S) -> V6<S> {
    std::array::from_fn(|_| zero.clone())
}

#[inline(always)]
pub fn zeros_m6<S: Scalar>(zero: &S) -> M6<S> {
    std::array::from_fn(|_| zeros(zero))
}

#[inline(always)]
fn mul<S: Scalar>(a: &S, b: &S) -> S {
    a.clone() * b.clone()
}

#[inline(always)]
fn cross3<S: Scalar>(a: &[S], b: &[S]) -> V3<S> {
    [
        mul(&a[1], &b[2]) - mul(&a[2], &b[1]),
        mul(&a[2], &b[0]) - mul(&a[0], &b[2]),
        mul(&a[0], &b[1]) - mul(&a[1], &b[0]),
    ]
}

/// m × x for motions (crm).
#[inline(always)]
pub fn cross<S: Scalar>(m: &V6<S>, x: &V6<S>) -> V6<S> {
    let (w, v) = m.split_at(3);
    let (xw, xv) = x.split_at(3);
    let (a, b, c) = (cross3(w, xw), cross3(w, xv), cross3(v, xw));
    let [b0, b1, b2] = b;
    let [c0, c1, c2] = c;
    let [a0, a1, a2] = a;
    [a0, a1, a2, b0 + c0, b1 + c1, b2 + c2]
}

/// m ×* f (crf).
#[inline(always)]
pub fn cross_force<S: Scalar>(m: &V6<S>, f: &V6<S>) -> V6<S> {
    let (w, v) = m.split_at(3);
    let (n, ff) = f.split_at(3);
    let (a, b, c) = (cross3(w, n), cross3(v, ff), cross3(w, ff));
    let [a0, a1, a2] = a;
    let [b0, b1, b2] = b;
    let [c0, c1, c2] = c;
    [a0 + b0, a1 + b1, a2 + b2, c0, c1, c2]
}

/// Σ aᵢ bᵢ, left to right (as f64's `sum`, whose fold starts at −0.0, the identity).
#[inline(always)]
pub fn dot<S: Scalar>(a: &V6<S>, b: &V6<S>) -> S {
    let mut s = mul(&a[0], &b[0]);
    for (x, y) in a.iter().zip(b).skip(1) {
        s = s + mul(x, y);
    }
    s
}

#[inline(always)]
pub fn add<S: Scalar>(a: &V6<S>, b: &V6<S>) -> V6<S> {
    let mut out = a.clone();
    out.iter_mut()
        .zip(b)
        .for_each(|(o, y)| *o = o.clone() + y.clone());
    out
}

/// a + c b.
#[inline(always)]
pub fn add_scaled<S: Scalar>(a: &V6<S>, c: &S, b: &V6<S>) -> V6<S> {
    let mut out = a.clone();
    out.iter_mut()
        .zip(b)
        .for_each(|(o, y)| *o = o.clone() + mul(c, y));
    out
}

/// c b.
#[inline(always)]
pub fn scaled<S: Scalar>(c: &S, b: &V6<S>) -> V6<S> {
    let mut out = b.clone();
    out.iter_mut().for_each(|o| *o = mul(c, o));
    out
}

/// M x.
#[inline(always)]
pub fn apply<S: Scalar>(m: &M6<S>, x: &V6<S>) -> V6<S> {
    let mut out = x.clone();
    out.iter_mut().zip(m).for_each(|(o, row)| *o = dot(row, x));
    out
}

#[inline(always)]
pub fn add_assign<S: Scalar>(a: &mut M6<S>, b: &M6<S>) {
    for (ra, rb) in a.iter_mut().zip(b) {
        for (x, y) in ra.iter_mut().zip(rb) {
            *x = x.clone() + y.clone();
        }
    }
}

/// a ← a − u uᵀ / d: the articulated inertia a joint passes to its parent.
#[inline(always)]
pub fn sub_outer<S: Scalar>(a: &mut M6<S>, u: &V6<S>, d: &S) {
    for (row, ur) in a.iter_mut().zip(u) {
        let k = ur.clone() / d.clone();
        row.iter_mut()
            .zip(u)
            .for_each(|(x, uc)| *x = x.clone() - mul(&k, uc));
    }
}

/// Σ rᵢ cᵢ over three constant coefficients, left to right.
#[inline(always)]
fn combine<S: Scalar>(r: [&S; 3], c: &V3<f64>) -> S {
    r[0].scale(c[0]) + r[1].scale(c[1]) + r[2].scale(c[2])
}

/// A motion in body coordinates, in the root frame, for the body placed at (E₀, p) (E₀ turns
/// root axes into the body's, p is its origin): ω = E₀ᵀ ω', v = E₀ᵀ v' + p × ω.
#[inline(always)]
pub fn motion_to_root<S: Scalar>(e: &M3<S>, p: &V3<S>, m: &V6<f64>) -> V6<S> {
    let rt = |x: &V3<f64>| -> V3<S> {
        std::array::from_fn(|i| combine([&e[0][i], &e[1][i], &e[2][i]], x))
    };
    let w = rt(&[m[0], m[1], m[2]]);
    let [v0, v1, v2] = rt(&[m[3], m[4], m[5]]);
    let [p0, p1, p2] = cross3(p, &w);
    let [w0, w1, w2] = w;
    [w0, w1, w2, v0 + p0, v1 + p1, v2 + p2]
}

/// A rigid body's inertia in the root frame (Xᵀ I X for X the root-to-body transform), from
/// its mass m, first moment h and rotational inertia A about its frame's origin: with
/// R = E₀ᵀ, g = R h and [a]×ᵀ[b]× = (a·b)𝟙 − b aᵀ,
/// h' = m p + g and A' = R A Rᵀ + m(|p|²𝟙 − p pᵀ) + 2(p·g)𝟙 − g pᵀ − p gᵀ. Written into `out`
/// (every entry) rather than returned: returned, the 6×6 result was a copy per body and the
/// call stayed out of line (together 2 % of an f64 forward dynamics' instructions).
#[inline(always)]
pub fn inertia_to_root<S: Scalar>(e: &M3<S>, p: &V3<S>, body: &Inertial<S>, out: &mut M6<S>) {
    let zero = p[0].lift(0.0);
    let (m, hb, a) = (&body.mass, &body.h, &body.inertia);
    // Loops over plain arrays, as the rest of this file, so that the f64 instance vectorises.
    let z3 = [zero.clone(), zero.clone(), zero.clone()];
    let mut g = z3.clone();
    for (r, g) in g.iter_mut().enumerate() {
        *g = dot3(&[&e[0][r], &e[1][r], &e[2][r]], hb);
    }
    // A E₀, then E₀ᵀ (A E₀) = R A Rᵀ.
    let mut ae = [z3.clone(), z3.clone(), z3.clone()];
    for (r, row) in ae.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = mul(&a[r][0], &e[0][c]) + mul(&a[r][1], &e[1][c]) + mul(&a[r][2], &e[2][c]);
        }
    }
    let (pp, pg) = (
        dot3(&[&p[0], &p[1], &p[2]], p),
        dot3(&[&p[0], &p[1], &p[2]], &g),
    );
    let mut h = z3;
    for (k, h) in h.iter_mut().enumerate() {
        *h = mul(m, &p[k]) + g[k].clone();
    }
    for r in 0..3 {
        for c in 0..3 {
            let rar =
                mul(&e[0][r], &ae[0][c]) + mul(&e[1][r], &ae[1][c]) + mul(&e[2][r], &ae[2][c]);
            let diag = if r == c {
                mul(m, &pp) + pg.scale(2.0)
            } else {
                zero.clone()
            };
            out[r][c] =
                rar + diag - mul(&mul(m, &p[r]), &p[c]) - mul(&g[r], &p[c]) - mul(&p[r], &g[c]);
            out[3 + r][3 + c] = if r == c { m.clone() } else { zero.clone() };
        }
    }
    // B = [h]× above the diagonal blocks, Bᵀ below.
    let hx = skew(&h, &zero);
    for r in 0..3 {
        for c in 0..3 {
            out[r][3 + c] = hx[r][c].clone();
            out[3 + c][r] = hx[r][c].clone();
        }
    }
}

/// x · y for x given by reference, left to right.
#[inline(always)]
fn dot3<S: Scalar>(x: &[&S; 3], y: &V3<S>) -> S {
    mul(x[0], &y[0]) + mul(x[1], &y[1]) + mul(x[2], &y[2])
}

/// [x]×.
#[inline(always)]
fn skew<S: Scalar>(x: &[S], zero: &S) -> M3<S> {
    let z = || zero.clone();
    [
        [z(), -x[2].clone(), x[1].clone()],
        [x[2].clone(), z(), -x[0].clone()],
        [-x[1].clone(), x[0].clone(), z()],
    ]
}

#[inline(always)]
fn mul3<S: Scalar>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            mul(&a[r][0], &b[0][c]) + mul(&a[r][1], &b[1][c]) + mul(&a[r][2], &b[2][c])
        })
    })
}

/// B = [v]×* I − I [v]× + [I v]⁻ ([h]⁻ d = d ×* h): the derivative of a body force
/// I a + v ×* I v along a change d of v that moves a by d × v. For a rigid body's
/// I = [[A, [h]×], [−[h]×, m𝟙]] at v = (ω, u) with momentum (hₙ, h_f) = I v, its right
/// column of blocks vanishes (h_f = m u + ω × h cancels it) and
///
///     B = [[[ω]× A − A [ω]× − [u]×[h]× − [h]×[u]× − [hₙ]×, 0], [−2 [h_f]×, 0]],
///
/// so only the two left blocks are kept: B d reads d's ω only.
#[derive(Debug, Clone, Copy)]
pub struct Variation<S = f64> {
    pub top: M3<S>,
    pub bottom: M3<S>,
}

impl<S: Scalar> Variation<S> {
    pub fn zero(zero: &S) -> Self {
        let m: M3<S> = std::array::from_fn(|_| std::array::from_fn(|_| zero.clone()));
        Self {
            top: m.clone(),
            bottom: m,
        }
    }

    #[inline]
    pub fn of(i: &M6<S>, v: &V6<S>, momentum: &V6<S>) -> Self {
        let zero = v[0].lift(0.0);
        let a: M3<S> = std::array::from_fn(|r| std::array::from_fn(|c| i[r][c].clone()));
        // [h]× is the upper right block.
        let h = [i[2][4].clone(), i[0][5].clone(), i[1][3].clone()];
        let (w, u) = (skew(&v[..3], &zero), skew(&v[3..], &zero));
        let hx = skew(&h, &zero);
        let (wa, aw, uh, hu) = (mul3(&w, &a), mul3(&a, &w), mul3(&u, &hx), mul3(&hx, &u));
        let hn = skew(&momentum[..3], &zero);
        let hf = skew(&momentum[3..], &zero);
        Self {
            top: std::array::from_fn(|r| {
                std::array::from_fn(|c| {
                    wa[r][c].clone()
                        - aw[r][c].clone()
                        - uh[r][c].clone()
                        - hu[r][c].clone()
                        - hn[r][c].clone()
                })
            }),
            bottom: std::array::from_fn(|r| std::array::from_fn(|c| hf[r][c].scale(-2.0))),
        }
    }

    #[inline]
    pub fn add_assign(&mut self, o: &Self) {
        for (a, b) in self.top.iter_mut().zip(&o.top) {
            a.iter_mut()
                .zip(b)
                .for_each(|(x, y)| *x = x.clone() + y.clone());
        }
        for (a, b) in self.bottom.iter_mut().zip(&o.bottom) {
            a.iter_mut()
                .zip(b)
                .for_each(|(x, y)| *x = x.clone() + y.clone());
        }
    }

    /// B d.
    #[inline]
    pub fn apply(&self, d: &V6<S>) -> V6<S> {
        let row = |m: &M3<S>, r: usize| {
            mul(&m[r][0], &d[0]) + mul(&m[r][1], &d[1]) + mul(&m[r][2], &d[2])
        };
        [
            row(&self.top, 0),
            row(&self.top, 1),
            row(&self.top, 2),
            row(&self.bottom, 0),
            row(&self.bottom, 1),
            row(&self.bottom, 2),
        ]
    }

    /// Bᵀ x.
    #[inline]
    pub fn apply_t(&self, x: &V6<S>) -> V6<S> {
        let zero = x[0].lift(0.0);
        let col = |c: usize| {
            let mut s = mul(&self.top[0][c], &x[0]) + mul(&self.bottom[0][c], &x[3]);
            for r in 1..3 {
                s = s + (mul(&self.top[r][c], &x[r]) + mul(&self.bottom[r][c], &x[3 + r]));
            }
            s
        };
        [col(0), col(1), col(2), zero.clone(), zero.clone(), zero]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition column by column: B e_c = v ×* (I e_c) − I (v × e_c) + e_c ×* h.
    fn variation_by_columns(i: &M6, v: &V6, h: &V6) -> M6 {
        let mut b = [[0.0; 6]; 6];
        for c in 0..6 {
            let col: V6 = std::array::from_fn(|r| i[r][c]);
            let mut e = ZERO6;
            e[c] = 1.0;
            let term = add(
                &add_scaled(&cross_force(v, &col), &-1.0, &apply(i, &cross(v, &e))),
                &cross_force(&e, h),
            );
            for (r, t) in term.iter().enumerate() {
                b[r][c] = *t;
            }
        }
        b
    }

    fn rigid_body() -> Inertial {
        let a = [[0.3, 0.02, -0.01], [0.02, 0.25, 0.03], [-0.01, 0.03, 0.2]];
        Inertial {
            mass: 1.7,
            h: [0.1, -0.2, 0.05],
            inertia: a,
            at_com: None,
        }
    }

    /// [a]×.
    fn skew(a: &V3<f64>) -> M3<f64> {
        [[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]]
    }

    /// A 6×6 matrix of 3×3 blocks [[p, q], [r, s]].
    fn blocks(p: &M3<f64>, q: &M3<f64>, r: &M3<f64>, s: &M3<f64>) -> M6 {
        std::array::from_fn(|i| {
            std::array::from_fn(|j| match (i < 3, j < 3) {
                (true, true) => p[i][j],
                (true, false) => q[i][j - 3],
                (false, true) => r[i - 3][j],
                (false, false) => s[i - 3][j - 3],
            })
        })
    }

    fn mul6(a: &M6, b: &M6) -> M6 {
        std::array::from_fn(|i| std::array::from_fn(|j| (0..6).map(|k| a[i][k] * b[k][j]).sum()))
    }

    fn placement() -> (M3<f64>, V3<f64>) {
        let (c, s) = (0.6f64.cos(), 0.6f64.sin());
        let e = [
            [c, s, 0.0],
            [-s * 0.8, c * 0.8, 0.6],
            [s * 0.6, -c * 0.6, 0.8],
        ];
        (e, [0.4, -0.3, 0.9])
    }

    /// The structured B equals the definition at a body placed off the root, to rounding
    /// (sums of a few products of O(1) terms: 1e-14).
    #[test]
    fn the_structured_variation_is_the_definition() {
        let (e, p) = placement();
        let mut i = [[f64::NAN; 6]; 6];
        inertia_to_root(&e, &p, &rigid_body(), &mut i);
        let v = [0.3, -1.1, 0.7, 0.5, 0.2, -0.9];
        let h = apply(&i, &v);
        let want = variation_by_columns(&i, &v, &h);
        let got = Variation::of(&i, &v, &h);
        for c in 0..6 {
            let mut x = ZERO6;
            x[c] = 1.0;
            let col = got.apply(&x);
            for r in 0..6 {
                assert!((col[r] - want[r][c]).abs() < 1e-14, "B[{r}][{c}]");
            }
            let row = got.apply_t(&x);
            for (k, w) in row.iter().enumerate() {
                assert!((w - want[c][k]).abs() < 1e-14, "Bᵀ[{k}][{c}]");
            }
        }
    }

    /// The closed form of the root-frame inertia equals Xᵀ I X by the spatial transform, to
    /// rounding (1e-14 on entries of size ≤ 2).
    #[test]
    fn the_root_inertia_is_the_transformed_one() {
        let (e, p) = placement();
        // Featherstone's definition: X = [[E, 0], [−E [p]×, E]] from root to body
        // coordinates, the body's I = [[Ī, [h]×], [[h]×ᵀ, m 𝟙]], and Xᵀ I X by 6×6 products.
        let b = rigid_body();
        let zero = [[0.0; 3]; 3];
        let m1 =
            std::array::from_fn(|i| std::array::from_fn(|j| if i == j { b.mass } else { 0.0 }));
        let hx = skew(&b.h);
        let hxt = std::array::from_fn(|i| std::array::from_fn(|j| hx[j][i]));
        let i_body = blocks(&b.inertia, &hx, &hxt, &m1);
        let px = skew(&p);
        let epx = std::array::from_fn(|i| {
            std::array::from_fn(|j| -(0..3).map(|k| e[i][k] * px[k][j]).sum::<f64>())
        });
        let x = blocks(&e, &zero, &epx, &e);
        let xt = std::array::from_fn(|i| std::array::from_fn(|j| x[j][i]));
        let want = mul6(&xt, &mul6(&i_body, &x));
        // NaN where an entry went unwritten.
        let mut got = [[f64::NAN; 6]; 6];
        inertia_to_root(&e, &p, &rigid_body(), &mut got);
        for r in 0..6 {
            for c in 0..6 {
                assert!((got[r][c] - want[r][c]).abs() < 1e-14, "[{r}][{c}]");
            }
        }
    }
}

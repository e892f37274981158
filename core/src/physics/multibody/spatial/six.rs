//! Spatial vectors and matrices as flat f64 arrays, for the algorithms that run in the root
//! frame on f64 only (`Data`'s): a motion is (ω, v), a force (n, f), an inertia or any other
//! motion-to-force map a 6×6 matrix. Plain arrays keep these loops free of the generic
//! `Scalar` clones and let the compiler vectorise them.

use super::{Force, Inertia, M3, Motion, V3};

pub type V6 = [f64; 6];
pub type M6 = [[f64; 6]; 6];

pub const ZERO6: V6 = [0.0; 6];

#[inline]
pub fn of_motion(m: &Motion<f64>) -> V6 {
    [m.w[0], m.w[1], m.w[2], m.v[0], m.v[1], m.v[2]]
}

#[inline]
pub fn of_force(f: &Force<f64>) -> V6 {
    [f.n[0], f.n[1], f.n[2], f.f[0], f.f[1], f.f[2]]
}

/// [[A, B], [Bᵀ, C]].
#[inline]
pub fn of_inertia(i: &Inertia<f64>) -> M6 {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| match (r < 3, c < 3) {
            (true, true) => i.a[r][c],
            (true, false) => i.b[r][c - 3],
            (false, true) => i.b[c][r - 3],
            (false, false) => i.c[r - 3][c - 3],
        })
    })
}

#[inline]
fn cross3(a: &[f64], b: &[f64]) -> V3<f64> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// m × x for motions (crm).
#[inline]
pub fn cross(m: &V6, x: &V6) -> V6 {
    let (w, v) = m.split_at(3);
    let (xw, xv) = x.split_at(3);
    let (a, b, c) = (cross3(w, xw), cross3(w, xv), cross3(v, xw));
    [a[0], a[1], a[2], b[0] + c[0], b[1] + c[1], b[2] + c[2]]
}

/// m ×* f (crf).
#[inline]
pub fn cross_force(m: &V6, f: &V6) -> V6 {
    let (w, v) = m.split_at(3);
    let (n, ff) = f.split_at(3);
    let (a, b, c) = (cross3(w, n), cross3(v, ff), cross3(w, ff));
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], c[0], c[1], c[2]]
}

#[inline]
pub fn dot(a: &V6, b: &V6) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[inline]
pub fn add(a: &V6, b: &V6) -> V6 {
    // Loops over fixed-size arrays rather than `array::from_fn`, which the compiler left as
    // an out-of-line call in the hot loops (5 % of a training step's time).
    let mut out = *a;
    out.iter_mut().zip(b).for_each(|(o, y)| *o += y);
    out
}

/// a + c b.
#[inline]
pub fn add_scaled(a: &V6, c: f64, b: &V6) -> V6 {
    let mut out = *a;
    out.iter_mut().zip(b).for_each(|(o, y)| *o += c * y);
    out
}

/// M x.
#[inline]
pub fn apply(m: &M6, x: &V6) -> V6 {
    let mut out = ZERO6;
    out.iter_mut().zip(m).for_each(|(o, row)| *o = dot(row, x));
    out
}

/// Mᵀ x.
#[inline]
pub fn apply_t(m: &M6, x: &V6) -> V6 {
    let mut out = ZERO6;
    for (row, &xr) in m.iter().zip(x) {
        for (o, &v) in out.iter_mut().zip(row) {
            *o += v * xr;
        }
    }
    out
}

#[inline]
pub fn add_assign(a: &mut M6, b: &M6) {
    for (ra, rb) in a.iter_mut().zip(b) {
        for (x, y) in ra.iter_mut().zip(rb) {
            *x += y;
        }
    }
}

/// A motion in body coordinates, in the root frame, for the body placed at (E₀, p) (E₀ turns
/// root axes into the body's, p is its origin): ω = E₀ᵀ ω', v = E₀ᵀ v' + p × ω.
#[inline]
pub fn motion_to_root(e: &M3<f64>, p: &V3<f64>, m: &Motion<f64>) -> V6 {
    let rt = |x: &V3<f64>| -> V3<f64> {
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = e[0][i] * x[0] + e[1][i] * x[1] + e[2][i] * x[2];
        }
        out
    };
    let w = rt(&m.w);
    let v = rt(&m.v);
    let pw = cross3(p, &w);
    [w[0], w[1], w[2], v[0] + pw[0], v[1] + pw[1], v[2] + pw[2]]
}

/// A rigid body's inertia in the root frame (Xᵀ I X for X the root-to-body transform), from
/// its mass m, first moment h and rotational inertia A about its frame's origin: with
/// R = E₀ᵀ, g = R h and [a]×ᵀ[b]× = (a·b)𝟙 − b aᵀ,
/// h' = m p + g and A' = R A Rᵀ + m(|p|²𝟙 − p pᵀ) + 2(p·g)𝟙 − g pᵀ − p gᵀ.
#[inline]
pub fn inertia_to_root(e: &M3<f64>, p: &V3<f64>, i: &Inertia<f64>) -> M6 {
    let m = i.mass();
    let hb = i.first_moment();
    let mut g = [0.0; 3];
    for (r, g) in g.iter_mut().enumerate() {
        *g = e[0][r] * hb[0] + e[1][r] * hb[1] + e[2][r] * hb[2];
    }
    // A E₀, then E₀ᵀ (A E₀) = R A Rᵀ.
    let mut ae = [[0.0; 3]; 3];
    for (r, row) in ae.iter_mut().enumerate() {
        for (c, x) in row.iter_mut().enumerate() {
            *x = i.a[r][0] * e[0][c] + i.a[r][1] * e[1][c] + i.a[r][2] * e[2][c];
        }
    }
    let (pp, pg) = (dot3(p, p), dot3(p, &g));
    let h = [m * p[0] + g[0], m * p[1] + g[1], m * p[2] + g[2]];
    let mut out = [[0.0; 6]; 6];
    for r in 0..3 {
        for c in 0..3 {
            let rar = e[0][r] * ae[0][c] + e[1][r] * ae[1][c] + e[2][r] * ae[2][c];
            let diag = if r == c { m * pp + 2.0 * pg } else { 0.0 };
            out[r][c] = rar + diag - m * p[r] * p[c] - g[r] * p[c] - p[r] * g[c];
        }
        out[3 + r][3 + r] = m;
    }
    // B = [h]× above the diagonal blocks, Bᵀ below.
    let hx = [[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]];
    for r in 0..3 {
        for c in 0..3 {
            out[r][3 + c] = hx[r][c];
            out[3 + c][r] = hx[r][c];
        }
    }
    out
}

#[inline]
fn dot3(a: &V3<f64>, b: &V3<f64>) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// [x]×.
#[inline]
fn skew(x: &[f64]) -> M3<f64> {
    [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]]
}

#[inline]
fn mul3(a: &M3<f64>, b: &M3<f64>) -> M3<f64> {
    std::array::from_fn(|r| {
        std::array::from_fn(|c| a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c])
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
#[derive(Debug, Clone, Copy, Default)]
pub struct Variation {
    pub top: M3<f64>,
    pub bottom: M3<f64>,
}

impl Variation {
    #[inline]
    pub fn of(i: &M6, v: &V6, momentum: &V6) -> Self {
        let a: M3<f64> = std::array::from_fn(|r| std::array::from_fn(|c| i[r][c]));
        // [h]× is the upper right block.
        let h = [i[2][4], i[0][5], i[1][3]];
        let (w, u) = (skew(&v[..3]), skew(&v[3..]));
        let hx = skew(&h);
        let (wa, aw, uh, hu) = (mul3(&w, &a), mul3(&a, &w), mul3(&u, &hx), mul3(&hx, &u));
        let hn = skew(&momentum[..3]);
        let hf = skew(&momentum[3..]);
        Self {
            top: std::array::from_fn(|r| {
                std::array::from_fn(|c| wa[r][c] - aw[r][c] - uh[r][c] - hu[r][c] - hn[r][c])
            }),
            bottom: std::array::from_fn(|r| std::array::from_fn(|c| -2.0 * hf[r][c])),
        }
    }

    #[inline]
    pub fn add_assign(&mut self, o: &Self) {
        for (a, b) in self.top.iter_mut().zip(&o.top) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        for (a, b) in self.bottom.iter_mut().zip(&o.bottom) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
    }

    /// B d.
    #[inline]
    pub fn apply(&self, d: &V6) -> V6 {
        let row = |m: &M3<f64>, r: usize| m[r][0] * d[0] + m[r][1] * d[1] + m[r][2] * d[2];
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
    pub fn apply_t(&self, x: &V6) -> V6 {
        let col = |c: usize| {
            (0..3)
                .map(|r| self.top[r][c] * x[r] + self.bottom[r][c] * x[3 + r])
                .sum::<f64>()
        };
        [col(0), col(1), col(2), 0.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::multibody::spatial::Xform;

    /// The definition column by column: B e_c = v ×* (I e_c) − I (v × e_c) + e_c ×* h.
    fn variation_by_columns(i: &M6, v: &V6, h: &V6) -> M6 {
        let mut b = [[0.0; 6]; 6];
        for c in 0..6 {
            let col: V6 = std::array::from_fn(|r| i[r][c]);
            let mut e = ZERO6;
            e[c] = 1.0;
            let term = add(
                &add_scaled(&cross_force(v, &col), -1.0, &apply(i, &cross(v, &e))),
                &cross_force(&e, h),
            );
            for (r, t) in term.iter().enumerate() {
                b[r][c] = *t;
            }
        }
        b
    }

    fn body() -> Inertia<f64> {
        let a = [[0.3, 0.02, -0.01], [0.02, 0.25, 0.03], [-0.01, 0.03, 0.2]];
        Inertia::rigid(1.7, &[0.1, -0.2, 0.05], &a)
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
        let i = inertia_to_root(&e, &p, &body());
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
        let want = of_inertia(&Xform { e, r: p }.inertia_to_parent(&body()));
        let got = inertia_to_root(&e, &p, &body());
        for r in 0..6 {
            for c in 0..6 {
                assert!((got[r][c] - want[r][c]).abs() < 1e-14, "[{r}][{c}]");
            }
        }
    }
}

//! Spatial vectors and matrices as flat f64 arrays, for the algorithms that run in the root
//! frame on f64 only (`Data`'s): a motion is (ω, v), a force (n, f), an inertia or any other
//! motion-to-force map a 6×6 matrix. Plain arrays keep these loops free of the generic
//! `Scalar` clones and let the compiler vectorise them.

use super::{Force, Inertia, M3, Motion, V3, Xform};

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
    std::array::from_fn(|k| a[k] + b[k])
}

/// a + c b.
#[inline]
pub fn add_scaled(a: &V6, c: f64, b: &V6) -> V6 {
    std::array::from_fn(|k| a[k] + c * b[k])
}

/// M x.
#[inline]
pub fn apply(m: &M6, x: &V6) -> V6 {
    std::array::from_fn(|r| dot(&m[r], x))
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
        std::array::from_fn(|i| e[0][i] * x[0] + e[1][i] * x[1] + e[2][i] * x[2])
    };
    let w = rt(&m.w);
    let v = rt(&m.v);
    let pw = cross3(p, &w);
    [w[0], w[1], w[2], v[0] + pw[0], v[1] + pw[1], v[2] + pw[2]]
}

/// A body inertia in the root frame (Xᵀ I X for X the root-to-body transform).
#[inline]
pub fn inertia_to_root(e: &M3<f64>, p: &V3<f64>, i: &Inertia<f64>) -> M6 {
    let x = Xform { e: *e, r: *p };
    of_inertia(&x.inertia_to_parent(i))
}

/// The matrix of m ↦ m ×* h, for the derivative of v ×* (I v) in v.
#[inline]
pub fn bar_cross(h: &V6) -> M6 {
    // d ×* h = (d_ω × h_n + d_v × h_f, d_ω × h_f) = (−h_n × d_ω − h_f × d_v, −h_f × d_ω).
    let minus_skew =
        |x: &[f64]| -> M3<f64> { [[0.0, x[2], -x[1]], [-x[2], 0.0, x[0]], [x[1], -x[0], 0.0]] };
    let (hn, hf) = (minus_skew(&h[..3]), minus_skew(&h[3..]));
    std::array::from_fn(|r| {
        std::array::from_fn(|c| match (r < 3, c < 3) {
            (true, true) => hn[r][c],
            (true, false) => hf[r][c - 3],
            (false, true) => hf[r - 3][c],
            (false, false) => 0.0,
        })
    })
}

/// B = [v]×* I − I [v]× + [h]⁻ (with [h]⁻ d = d ×* h): the derivative of the body force
/// I a + v ×* I v along a change d of v that moves a by d × v. Column by column: (B)e_c =
/// v ×* (I e_c) − I (v × e_c) + e_c ×* h.
#[inline]
pub fn velocity_variation(i: &M6, v: &V6, h: &V6) -> M6 {
    let mut b = bar_cross(h);
    for c in 0..6 {
        let col: V6 = std::array::from_fn(|r| i[r][c]);
        let mut e = ZERO6;
        e[c] = 1.0;
        let term = add_scaled(&cross_force(v, &col), -1.0, &apply(i, &cross(v, &e)));
        for (r, t) in term.iter().enumerate() {
            b[r][c] += t;
        }
    }
    b
}

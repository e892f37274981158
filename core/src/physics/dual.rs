//! Forward-mode dual numbers: a value and its partial derivatives with respect to a fixed set
//! of input directions (the generalized coordinates q₁…qₙ, or a linearization's (x, u)).
//!
//! The one forward-mode family of the core, over any [`Scalar`]: `f64` for a single state,
//! batch columns, the training tape's values, and itself (`Dual<Dual<f64>>`: second
//! derivatives). Missing or `None` tangents are exact zeros and cost no arithmetic, which
//! matters when the scalar is a column of the training tape: parameters and constants carry
//! no tangent at all. The tangents live inline, at most `N` of them (fixed when the type is
//! named, so a caller picks the width its directions need): no operation allocates.

use super::scalar::Scalar;
use std::ops::{Add, Div, Mul, Neg, Range, Sub};

use arrayvec::ArrayVec;

/// The tangents of one dual number, inline: at most `N`, only those in use initialized.
pub type Tangents<S, const N: usize> = ArrayVec<Option<S>, N>;

/// The directions a dual number carries by default (a linearization's 2n + m for the
/// templates' systems, a double pendulum's ∂/∂q twice over): a derivative in more directions
/// runs in groups of this many ([`groups`]), each group's values computed again, which costs
/// less than tangents on the heap did and keeps every dual number a fixed size.
pub const WIDTH: usize = 8;

/// The directions 0..n in groups of at most [`WIDTH`].
pub fn groups(n: usize) -> impl Iterator<Item = Range<usize>> + Clone {
    (0..n).step_by(WIDTH).map(move |s| s..(s + WIDTH).min(n))
}

#[derive(Debug, Clone)]
pub struct Dual<S, const N: usize = WIDTH> {
    pub v: S,
    /// ∂v/∂x_k for each direction k; `None` (or beyond the end) means zero.
    pub d: Tangents<S, N>,
}

impl<S: Scalar, const N: usize> Dual<S, N> {
    pub fn constant(v: S) -> Self {
        Self {
            v,
            d: Tangents::new(),
        }
    }

    pub fn new(v: S, d: impl IntoIterator<Item = Option<S>>) -> Self {
        Self {
            v,
            d: d.into_iter().collect(),
        }
    }

    /// The input variable number `k` of `n`, with tangent `seed` (1 in direction k).
    pub fn variable(v: S, k: usize, n: usize, seed: S) -> Self {
        assert!(n <= N, "{n} directions for a dual number of {N}");
        let mut d: Tangents<S, N> = std::iter::repeat_n(None, n).collect();
        d[k] = Some(seed);
        Self { v, d }
    }

    /// `x` as dual numbers in the directions `dirs` of x's coordinates: x_k (k in `dirs`)
    /// carries `seed` in direction k − dirs.start, every other coordinate is a constant.
    pub fn seeded(x: &[S], seed: &S, dirs: Range<usize>) -> Vec<Self> {
        (x.iter().enumerate())
            .map(|(k, xk)| match dirs.contains(&k) {
                true => Self::variable(xk.clone(), k - dirs.start, dirs.len(), seed.clone()),
                false => Self::constant(xk.clone()),
            })
            .collect()
    }

    pub fn tangent(&self, k: usize) -> Option<&S> {
        self.d.get(k).and_then(Option::as_ref)
    }

    /// Chain rule for a unary function with derivative `dfdv` at `self.v`.
    fn chain(&self, v: S, dfdv: impl Fn() -> S) -> Self {
        if self.d.iter().all(Option::is_none) {
            return Self::constant(v);
        }
        let f = dfdv();
        let d = self
            .d
            .iter()
            .map(|t| t.as_ref().map(|t| f.clone() * t.clone()))
            .collect();
        Self { v, d }
    }
}

fn zip_tangents<S: Clone, const N: usize>(
    a: &[Option<S>],
    b: &[Option<S>],
    f: impl Fn(Option<&S>, Option<&S>) -> Option<S>,
) -> Tangents<S, N> {
    let n = a.len().max(b.len());
    (0..n)
        .map(|k| {
            f(
                a.get(k).and_then(Option::as_ref),
                b.get(k).and_then(Option::as_ref),
            )
        })
        .collect()
}

impl<S: Scalar, const N: usize> Add for Dual<S, N> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        let d = zip_tangents(&self.d, &o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => Some(a.clone() + b.clone()),
            (Some(a), None) => Some(a.clone()),
            (None, Some(b)) => Some(b.clone()),
            (None, None) => None,
        });
        Self { v: self.v + o.v, d }
    }
}

impl<S: Scalar, const N: usize> Sub for Dual<S, N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        let d = zip_tangents(&self.d, &o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => Some(a.clone() - b.clone()),
            (Some(a), None) => Some(a.clone()),
            (None, Some(b)) => Some(-b.clone()),
            (None, None) => None,
        });
        Self { v: self.v - o.v, d }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)] // the product rule
impl<S: Scalar, const N: usize> Mul for Dual<S, N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let d = zip_tangents(&self.d, &o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => Some(a.clone() * o.v.clone() + self.v.clone() * b.clone()),
            (Some(a), None) => Some(a.clone() * o.v.clone()),
            (None, Some(b)) => Some(self.v.clone() * b.clone()),
            (None, None) => None,
        });
        Self { v: self.v * o.v, d }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)] // the quotient rule
impl<S: Scalar, const N: usize> Div for Dual<S, N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let v = self.v.clone() / o.v.clone();
        // (a/b)' = (a' − (a/b) b') / b
        let d = zip_tangents(&self.d, &o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => Some((a.clone() - v.clone() * b.clone()) / o.v.clone()),
            (Some(a), None) => Some(a.clone() / o.v.clone()),
            (None, Some(b)) => Some(-(v.clone() * b.clone()) / o.v.clone()),
            (None, None) => None,
        });
        Self { v, d }
    }
}

impl<S: Scalar, const N: usize> Neg for Dual<S, N> {
    type Output = Self;
    fn neg(self) -> Self {
        let mut d = self.d;
        for t in d.iter_mut() {
            *t = t.take().map(|t| -t);
        }
        Self { v: -self.v, d }
    }
}

impl<S: Scalar, const N: usize> Scalar for Dual<S, N> {
    fn cos(&self) -> Self {
        self.chain(self.v.cos(), || -self.v.sin())
    }
    fn sin(&self) -> Self {
        self.chain(self.v.sin(), || self.v.cos())
    }
    fn sqrt(&self) -> Self {
        let r = self.v.sqrt();
        self.chain(r.clone(), || r.scale(2.0).recip_like())
    }
    fn exp(&self) -> Self {
        let e = self.v.exp();
        self.chain(e.clone(), || e.clone())
    }
    fn ln(&self) -> Self {
        self.chain(self.v.ln(), || self.v.recip_like())
    }
    fn atan2(&self, x: &Self) -> Self {
        // ∂atan2(y, x) = (x dy − y dx) / (x² + y²)
        let r2 = self.v.square() + x.v.square();
        let d = zip_tangents(&self.d, &x.d, |dy, dx| {
            let num = match (dy, dx) {
                (None, None) => return None,
                (Some(dy), None) => x.v.clone() * dy.clone(),
                (None, Some(dx)) => -(self.v.clone() * dx.clone()),
                (Some(dy), Some(dx)) => x.v.clone() * dy.clone() - self.v.clone() * dx.clone(),
            };
            Some(num / r2.clone())
        });
        Self {
            v: self.v.atan2(&x.v),
            d,
        }
    }
    fn sigmoid(&self) -> Self {
        let s = self.v.sigmoid();
        // σ' = σ(1 − σ)
        self.chain(s.clone(), || s.clone() * (-s.clone()).shift(1.0))
    }
    fn softplus(&self) -> Self {
        self.chain(self.v.softplus(), || self.v.sigmoid())
    }
    fn scale(&self, c: f64) -> Self {
        Self {
            v: self.v.scale(c),
            d: self
                .d
                .iter()
                .map(|t| t.as_ref().map(|t| t.scale(c)))
                .collect(),
        }
    }
    fn shift(&self, c: f64) -> Self {
        Self {
            v: self.v.shift(c),
            d: self.d.clone(),
        }
    }
    fn tanh(&self) -> Self {
        let h = self.v.tanh();
        // tanh' = 1 − h²
        self.chain(h.clone(), || (-h.square()).shift(1.0))
    }
    fn lift(&self, c: f64) -> Self {
        Self::constant(self.v.lift(c))
    }
}

/// 1/x as x / (x · x). `Scalar::lift(1.0) / x` would do too, but served models' outputs were
/// computed in this form, and another form changes their last bits (tests/suite/compat.rs).
trait RecipLike: Scalar {
    fn recip_like(&self) -> Self {
        self.clone() / self.square()
    }
}
impl<S: Scalar> RecipLike for S {}

#[cfg(test)]
mod tests {
    use super::*;

    fn var(x: f64) -> Dual<f64> {
        Dual::variable(x, 0, 1, 1.0)
    }

    /// Every rule against a central difference (h = 1e-6: truncation ~h² ≈ 1e-12, rounding
    /// ~ε/h ≈ 1e-10, so 1e-8 is a safe bound for these O(1) functions).
    #[test]
    fn rules_match_central_differences() {
        type Rule = (&'static str, fn(Dual<f64>) -> Dual<f64>);
        let fs: Vec<Rule> = vec![
            ("cos", |x| x.cos()),
            ("sin", |x| x.sin()),
            ("sqrt", |x| x.sqrt()),
            ("exp", |x| x.exp()),
            ("sigmoid", |x| x.sigmoid()),
            ("softplus", |x| x.softplus()),
            ("mul", |x| x.clone() * x.sin()),
            ("div", |x| x.cos() / x.exp()),
            ("sub", |x| x.scale(3.0) - x.square()),
            ("neg", |x| -x.shift(2.0)),
            ("tanh", |x| x.scale(0.7).tanh()),
            ("ln", |x| x.shift(0.5).ln()),
            ("atan2", |x| x.sin().atan2(&x.exp())),
        ];
        for (name, f) in fs {
            for &x in &[0.3, 1.1, 2.5] {
                let h = 1e-6;
                let fd = (f(Dual::constant(x + h)).v - f(Dual::constant(x - h)).v) / (2.0 * h);
                let ad = f(var(x)).tangent(0).copied().unwrap_or(0.0);
                assert!((fd - ad).abs() < 1e-8, "{name} at {x}: {ad} vs {fd}");
            }
        }
    }

    #[test]
    fn hyper_dual_gives_second_derivative() {
        // d²/dx² sin(x)·x = 2cos x − x sin x
        let x = 0.7;
        let inner: Dual<f64> = Dual::variable(x, 0, 1, 1.0);
        let outer: Dual<Dual<f64>> = Dual::variable(inner, 0, 1, Dual::constant(1.0));
        let y = outer.clone() * outer.sin();
        let d2 = y.tangent(0).unwrap().tangent(0).copied().unwrap();
        assert!((d2 - (2.0 * x.cos() - x * x.sin())).abs() < 1e-14);
    }
}

//! Forward-mode dual numbers: a value and its partial derivatives with respect to a fixed set
//! of input directions (the generalized coordinates q₁…qₙ, or a linearization's (x, u)).
//!
//! The one forward-mode family of the core: its rules are written once, over any [`Scalar`]
//! (`f64` for a single state, batch columns, the training tape's values, and itself,
//! `Dual<Dual<f64>>` for second derivatives), and over where the tangents are kept
//! ([`Tangents`]), always inline, so no operation allocates:
//! - [`Sparse`] (the default): at most N optional tangents, a missing one an exact zero that
//!   costs no arithmetic, which matters when the scalar is a column of the training tape
//!   (parameters and constants carry no tangent at all);
//! - [`Dense`] ([`Jet`]): N plain f64 tangents, each operation one loop over them that the
//!   compiler vectorises, for recursions where every value soon depends on every direction
//!   (a robot's step Jacobian over its 2n + m directions: 15× faster than sparse ones there;
//!   every state's Linearize, `infer::continuous::Outer`).

use super::scalar::Scalar;
use crate::arena::{AVec, Arena, CollectIn};
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Range, Sub, SubAssign};

pub use super::tangents::{Dense, Sparse, Tangents, WIDTH};

/// The directions 0..n in groups of as many as a dual number over `S` holds
/// ([`Scalar::Tangents`]).
pub fn groups<S: Scalar>(n: usize) -> impl Iterator<Item = Range<usize>> + Clone {
    groups_of(n, <S::Tangents as Tangents<S>>::WIDTH)
}

/// The directions 0..n in groups of at most `width`.
pub fn groups_of(n: usize, width: usize) -> impl Iterator<Item = Range<usize>> + Clone {
    (0..n).step_by(width).map(move |s| s..(s + width).min(n))
}

/// A value with its tangents, kept as `T` says: [`WIDTH`] sparse ones unless named otherwise.
#[derive(Debug, Clone)]
pub struct Dual<S: Scalar, T = <S as Scalar>::Tangents> {
    pub v: S,
    /// ∂v/∂x_k for each direction k.
    d: T,
}

/// A dual number over f64 with N dense tangents.
pub type Jet<const N: usize> = Dual<f64, Dense<N>>;

impl<const N: usize> Jet<N> {
    pub fn from_dense(v: f64, d: [f64; N]) -> Self {
        Self { v, d: Dense(d) }
    }

    /// Every tangent, zeros included.
    pub fn dense(&self) -> &[f64; N] {
        &self.d.0
    }
}

impl<S: Scalar, T: Tangents<S>> Dual<S, T> {
    pub fn constant(v: S) -> Self {
        Self { v, d: T::none() }
    }

    pub fn new(v: S, d: impl IntoIterator<Item = Option<S>>) -> Self {
        Self {
            v,
            d: T::from_options(d),
        }
    }

    /// The input variable number `k` of `n`, with tangent `seed` (1 in direction k).
    pub fn variable(v: S, k: usize, n: usize, seed: S) -> Self {
        let mut seed = Some(seed);
        Self::new(v, (0..n).map(|i| if i == k { seed.take() } else { None }))
    }

    /// `x` as dual numbers in the directions `dirs` of x's coordinates: x_k (k in `dirs`)
    /// carries `seed` in direction k − dirs.start, every other coordinate is a constant.
    pub fn seeded(x: &[S], seed: &S, dirs: Range<usize>) -> Vec<Self> {
        Self::seeds(x, seed, dirs).collect()
    }

    /// [`Dual::seeded`] in an arena.
    pub fn seeded_in<'a>(a: &'a Arena, x: &[S], seed: &S, dirs: Range<usize>) -> AVec<'a, Self> {
        Self::seeds(x, seed, dirs).collect_in(a)
    }

    fn seeds(x: &[S], seed: &S, dirs: Range<usize>) -> impl Iterator<Item = Self> {
        (x.iter().enumerate()).map(move |(k, xk)| match dirs.contains(&k) {
            true => Self::variable(xk.clone(), k - dirs.start, dirs.len(), seed.clone()),
            false => Self::constant(xk.clone()),
        })
    }

    /// Direction k's tangent; `None` is a zero.
    pub fn tangent(&self, k: usize) -> Option<&S> {
        self.d.get(k)
    }

    /// How many directions may carry a tangent: every one beyond is zero.
    pub fn dirs(&self) -> usize {
        self.d.dirs()
    }

    /// Chain rule for a unary function with derivative `dfdv` at `self.v`.
    fn chain(&self, v: S, dfdv: impl Fn() -> S) -> Self {
        if self.d.is_none() {
            return Self::constant(v);
        }
        let f = dfdv();
        Self {
            v,
            d: self.d.map(|t| f.clone() * t.clone()),
        }
    }
}

/// The operators by value, as the rules in place below: one copy of the rules.
macro_rules! by_value {
    ($trait:ident, $method:ident, $op:tt) => {
        impl<S: Scalar, T: Tangents<S>> $trait for Dual<S, T> {
            type Output = Self;
            fn $method(mut self, o: Self) -> Self {
                self $op &o;
                self
            }
        }
    };
}

by_value!(Add, add, +=);
by_value!(Sub, sub, -=);
by_value!(Mul, mul, *=);
by_value!(Div, div, /=);

impl<S: Scalar, T: Tangents<S>> Neg for Dual<S, T> {
    type Output = Self;
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.d.map_owned(|t| -t),
        }
    }
}

// The sum, product and quotient rules, in place: a wide value (a dual number over a `Pack`)
// is updated where it lies instead of copied into each intermediate. Each tangent's
// operations keep the order the answers were recorded with: a′ b + a b′, (a′ − (a/b) b′) / b.

impl<S: Scalar, T: Tangents<S>> AddAssign<&Self> for Dual<S, T> {
    fn add_assign(&mut self, o: &Self) {
        self.d.update(&o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => *a += b,
            (a @ None, Some(b)) => *a = Some(b.clone()),
            (_, None) => {}
        });
        self.v += &o.v;
    }
}

impl<S: Scalar, T: Tangents<S>> SubAssign<&Self> for Dual<S, T> {
    fn sub_assign(&mut self, o: &Self) {
        self.d.update(&o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => *a -= b,
            (a @ None, Some(b)) => *a = Some(-b.clone()),
            (_, None) => {}
        });
        self.v -= &o.v;
    }
}

#[allow(clippy::suspicious_op_assign_impl)] // the product rule
impl<S: Scalar, T: Tangents<S>> MulAssign<&Self> for Dual<S, T> {
    fn mul_assign(&mut self, o: &Self) {
        let v = &self.v;
        self.d.update(&o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => {
                *a *= &o.v;
                *a += &product(v, b);
            }
            (Some(a), None) => *a *= &o.v,
            (a @ None, Some(b)) => *a = Some(product(v, b)),
            (None, None) => {}
        });
        self.v *= &o.v;
    }
}

#[allow(clippy::suspicious_op_assign_impl)] // the quotient rule
impl<S: Scalar, T: Tangents<S>> DivAssign<&Self> for Dual<S, T> {
    fn div_assign(&mut self, o: &Self) {
        self.v /= &o.v;
        let v = &self.v;
        self.d.update(&o.d, |a, b| match (a, b) {
            (Some(a), Some(b)) => {
                *a -= &product(v, b);
                *a /= &o.v;
            }
            (Some(a), None) => *a /= &o.v,
            (a @ None, Some(b)) => {
                let mut t = -product(v, b);
                t /= &o.v;
                *a = Some(t);
            }
            (None, None) => {}
        });
    }
}

/// a · b, one copy of a.
fn product<S: Scalar>(a: &S, b: &S) -> S {
    let mut p = a.clone();
    p *= b;
    p
}

impl<S: Scalar, T: Tangents<S>> Scalar for Dual<S, T> {
    type Tangents = Sparse<Self, WIDTH>;
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
        let d = self.d.zip(&x.d, |dy, dx| {
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
            d: self.d.map(|t| t.scale(c)),
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

    /// Dense tangents run the same rules as sparse ones: with every direction seeded, the
    /// same operations in the same order, so the same numbers to the bit.
    #[test]
    fn dense_tangents_equal_sparse_ones() {
        type Pair = (Jet<2>, Dual<f64>);
        type Rule = (&'static str, fn(Pair) -> Pair);
        let fs: Vec<Rule> = vec![
            ("cos", |(j, d)| (j.cos(), d.cos())),
            ("sqrt", |(j, d)| (j.sqrt(), d.sqrt())),
            ("ln", |(j, d)| (j.ln(), d.ln())),
            ("softplus", |(j, d)| (j.softplus(), d.softplus())),
            ("tanh", |(j, d)| (j.tanh(), d.tanh())),
            ("mul", |(j, d)| (j.clone() * j.sin(), d.clone() * d.sin())),
            ("div", |(j, d)| (j.cos() / j.exp(), d.cos() / d.exp())),
            ("sub", |(j, d)| {
                (j.scale(3.0) - j.square(), d.scale(3.0) - d.square())
            }),
            ("neg", |(j, d)| (-j.shift(2.0), -d.shift(2.0))),
            ("atan2", |(j, d)| (j.atan2(&j.cos()), d.atan2(&d.cos()))),
        ];
        for (name, f) in fs {
            for x in [0.3, 1.1, 2.5] {
                let seeds = [Some(1.0), Some(-0.5)];
                let (a, b) = f((Jet::new(x, seeds), Dual::new(x, seeds)));
                assert_eq!(a.v.to_bits(), b.v.to_bits(), "{name}");
                for k in 0..2 {
                    assert_eq!(a.tangent(k), b.tangent(k), "{name} at {x}: {a:?} vs {b:?}");
                }
            }
        }
    }

    /// A missing tangent is an exact zero: each rule's branches for one side without a
    /// tangent give what the dense rules give with a 0 there, to the bit.
    #[test]
    fn missing_tangents_act_as_zeros() {
        type Op = fn(&mut Dual<f64>, &Dual<f64>);
        type DenseOp = fn(&mut Jet<2>, &Jet<2>);
        let ops: [(&str, Op, DenseOp); 4] = [
            ("add", |a, b| *a += b, |a, b| *a += b),
            ("sub", |a, b| *a -= b, |a, b| *a -= b),
            ("mul", |a, b| *a *= b, |a, b| *a *= b),
            ("div", |a, b| *a /= b, |a, b| *a /= b),
        ];
        let patterns = [[Some(0.7), None], [None, Some(-1.3)], [None, None]];
        for (name, sparse, dense) in ops {
            for ta in patterns {
                for tb in patterns {
                    let (mut a, b) = (Dual::new(1.9, ta), Dual::new(-0.6, tb));
                    let zero = |t: [Option<f64>; 2]| t.map(|t| Some(t.unwrap_or(0.0)));
                    let (mut ja, jb) = (Jet::new(1.9, zero(ta)), Jet::new(-0.6, zero(tb)));
                    sparse(&mut a, &b);
                    dense(&mut ja, &jb);
                    assert_eq!(a.v.to_bits(), ja.v.to_bits(), "{name}");
                    for k in 0..2 {
                        let got = a.tangent(k).copied().unwrap_or(0.0);
                        assert_eq!(got, ja.dense()[k], "{name} {ta:?} {tb:?} direction {k}");
                    }
                }
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

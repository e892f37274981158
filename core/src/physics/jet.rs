//! Forward-mode dual numbers over f64 with a fixed number N of dense tangents, stored inline:
//! `Copy`, no allocation, and each operation a loop over N that the compiler vectorises. Where
//! every value soon depends on every direction (a recursion over a robot's joints, with 2n
//! directions for ∂/∂q and ∂/∂q̇), this is much faster than [`Dual`](super::dual::Dual), whose
//! optional tangents pay for sparsity and spill to the heap beyond eight directions.

use super::scalar::Scalar;
use std::ops::{Add, Div, Mul, Neg, Sub};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jet<const N: usize> {
    pub v: f64,
    /// ∂v/∂x_k for each direction k.
    pub d: [f64; N],
}

impl<const N: usize> Jet<N> {
    pub fn constant(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }

    /// The input variable number `k` (tangent 1 in direction k).
    pub fn variable(v: f64, k: usize) -> Self {
        let mut d = [0.0; N];
        d[k] = 1.0;
        Self { v, d }
    }

    /// Chain rule for a unary function with value `v` and derivative `f` at `self.v`.
    fn chain(&self, v: f64, f: f64) -> Self {
        Self {
            v,
            d: self.d.map(|t| f * t),
        }
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            v: self.v + o.v,
            d: std::array::from_fn(|k| self.d[k] + o.d[k]),
        }
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self {
            v: self.v - o.v,
            d: std::array::from_fn(|k| self.d[k] - o.d[k]),
        }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)] // the product rule
impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self {
            v: self.v * o.v,
            d: std::array::from_fn(|k| self.d[k] * o.v + self.v * o.d[k]),
        }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)] // the quotient rule
impl<const N: usize> Div for Jet<N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        // (a/b)' = (a' − (a/b) b') / b
        let r = 1.0 / o.v;
        Self {
            v,
            d: std::array::from_fn(|k| (self.d[k] - v * o.d[k]) * r),
        }
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.d.map(|t| -t),
        }
    }
}

impl<const N: usize> Scalar for Jet<N> {
    fn cos(&self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s)
    }
    fn sin(&self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c)
    }
    fn sqrt(&self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, 0.5 / r)
    }
    fn exp(&self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn ln(&self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    fn atan2(&self, x: &Self) -> Self {
        // ∂atan2(y, x) = (x dy − y dx) / (x² + y²)
        let r2 = self.v * self.v + x.v * x.v;
        Self {
            v: self.v.atan2(x.v),
            d: std::array::from_fn(|k| (x.v * self.d[k] - self.v * x.d[k]) / r2),
        }
    }
    fn sigmoid(&self) -> Self {
        let s = Scalar::sigmoid(&self.v);
        self.chain(s, s * (1.0 - s))
    }
    fn softplus(&self) -> Self {
        self.chain(Scalar::softplus(&self.v), Scalar::sigmoid(&self.v))
    }
    fn scale(&self, c: f64) -> Self {
        self.chain(c * self.v, c)
    }
    fn shift(&self, c: f64) -> Self {
        Self {
            v: self.v + c,
            d: self.d,
        }
    }
    fn tanh(&self) -> Self {
        let h = self.v.tanh();
        self.chain(h, 1.0 - h * h)
    }
    fn lift(&self, c: f64) -> Self {
        Self::constant(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::dual::Dual;

    /// Every rule equals `Dual`'s (two directions, both seeded).
    #[test]
    fn rules_equal_dual_numbers() {
        type Pair = (Jet<2>, Dual<f64>);
        type Rule = (&'static str, fn(Pair) -> Pair);
        let fs: Vec<Rule> = vec![
            ("cos", |(j, d)| (j.cos(), d.cos())),
            ("sin", |(j, d)| (j.sin(), d.sin())),
            ("sqrt", |(j, d)| (j.sqrt(), d.sqrt())),
            ("exp", |(j, d)| (j.exp(), d.exp())),
            ("ln", |(j, d)| (j.ln(), d.ln())),
            ("sigmoid", |(j, d)| (j.sigmoid(), d.sigmoid())),
            ("softplus", |(j, d)| (j.softplus(), d.softplus())),
            ("tanh", |(j, d)| (j.tanh(), d.tanh())),
            ("mul", |(j, d)| (j * j.sin(), d.clone() * d.sin())),
            ("div", |(j, d)| (j.cos() / j.exp(), d.cos() / d.exp())),
            ("sub", |(j, d)| {
                (j.scale(3.0) - j.square(), d.scale(3.0) - d.square())
            }),
            ("neg", |(j, d)| (-j.shift(2.0), -d.shift(2.0))),
            ("atan2", |(j, d)| (j.atan2(&j.cos()), d.atan2(&d.cos()))),
        ];
        for (name, f) in fs {
            for x in [0.3, 1.1, 2.5] {
                let j = Jet::<2> {
                    v: x,
                    d: [1.0, -0.5],
                };
                let d = Dual::new(x, [Some(1.0), Some(-0.5)]);
                let (a, b) = f((j, d));
                assert!((a.v - b.v).abs() < 1e-15, "{name}");
                for k in 0..2 {
                    let t = b.tangent(k).copied().unwrap_or(0.0);
                    assert!((a.d[k] - t).abs() < 1e-13, "{name} at {x}: {a:?} vs {b:?}");
                }
            }
        }
    }
}

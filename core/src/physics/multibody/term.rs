//! A value that is either a known constant or a [`Scalar`]: rigid-body kinematics is mostly
//! constant geometry (joint origins, axes) times a few joint-dependent values, and on Burn
//! tensors every operation allocates. Arithmetic on constants happens in f64, a product with
//! 0 or 1 costs nothing, and a constant enters a scalar expression as `scale` or `shift`.

use std::ops::{Add, Div, Mul, Neg, Sub};

use crate::physics::scalar::Scalar;

#[derive(Debug, Clone)]
pub enum Term<S> {
    C(f64),
    V(S),
}

pub use Term::{C, V};

impl<S: Scalar> Term<S> {
    /// As a scalar of the kind of `like`.
    pub fn value(self, like: &S) -> S {
        match self {
            C(c) => like.lift(c),
            V(x) => x,
        }
    }
}

impl<S: Scalar> Add for Term<S> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        match (self, o) {
            (C(a), C(b)) => C(a + b),
            (C(a), V(x)) | (V(x), C(a)) if a == 0.0 => V(x),
            (C(a), V(x)) | (V(x), C(a)) => V(x.shift(a)),
            (V(x), V(y)) => V(x + y),
        }
    }
}

impl<S: Scalar> Neg for Term<S> {
    type Output = Self;
    fn neg(self) -> Self {
        match self {
            C(a) => C(-a),
            V(x) => V(-x),
        }
    }
}

impl<S: Scalar> Sub for Term<S> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        self + (-o)
    }
}

impl<S: Scalar> Mul for Term<S> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        match (self, o) {
            (C(a), C(b)) => C(a * b),
            (C(a), V(_)) | (V(_), C(a)) if a == 0.0 => C(0.0),
            (C(a), V(x)) | (V(x), C(a)) if a == 1.0 => V(x),
            (C(a), V(x)) | (V(x), C(a)) => V(x.scale(a)),
            (V(x), V(y)) => V(x * y),
        }
    }
}

pub fn constant_vec<S>(v: [f64; 3]) -> [Term<S>; 3] {
    v.map(C)
}

pub fn constant_mat<S>(m: [[f64; 3]; 3]) -> [[Term<S>; 3]; 3] {
    m.map(|r| r.map(C))
}

impl<S: Scalar> Div for Term<S> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        match (self, o) {
            (C(a), C(b)) => C(a / b),
            (V(x), C(b)) => V(x.clone() / x.lift(b)),
            (C(a), V(y)) => V(y.lift(a) / y),
            (V(x), V(y)) => V(x / y),
        }
    }
}

/// A function of one value: in f64 on a constant, on the scalar otherwise.
fn unary<S>(t: &Term<S>, c: impl Fn(f64) -> f64, v: impl Fn(&S) -> S) -> Term<S> {
    match t {
        C(a) => C(c(*a)),
        V(x) => V(v(x)),
    }
}

/// Constants fold in f64, so the 3-vector algebra of `spatial` runs on terms as it does on
/// any scalar.
impl<S: Scalar> Scalar for Term<S> {
    fn cos(&self) -> Self {
        unary(self, f64::cos, S::cos)
    }
    fn sin(&self) -> Self {
        unary(self, f64::sin, S::sin)
    }
    fn sqrt(&self) -> Self {
        unary(self, f64::sqrt, S::sqrt)
    }
    fn exp(&self) -> Self {
        unary(self, f64::exp, S::exp)
    }
    fn ln(&self) -> Self {
        unary(self, f64::ln, S::ln)
    }
    fn atan2(&self, x: &Self) -> Self {
        match (self, x) {
            (C(y), C(x)) => C(f64::atan2(*y, *x)),
            (V(y), C(x)) => V(y.atan2(&y.lift(*x))),
            (C(y), V(x)) => V(x.lift(*y).atan2(x)),
            (V(y), V(x)) => V(y.atan2(x)),
        }
    }
    fn sigmoid(&self) -> Self {
        unary(self, |a| a.sigmoid(), S::sigmoid)
    }
    fn softplus(&self) -> Self {
        unary(self, |a| a.softplus(), S::softplus)
    }
    fn scale(&self, c: f64) -> Self {
        unary(self, |a| c * a, |x| x.scale(c))
    }
    fn shift(&self, c: f64) -> Self {
        unary(self, |a| a + c, |x| x.shift(c))
    }
    fn tanh(&self) -> Self {
        unary(self, f64::tanh, S::tanh)
    }
    fn lift(&self, c: f64) -> Self {
        C(c)
    }
}

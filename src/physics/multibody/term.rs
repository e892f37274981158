//! A value that is either a known constant or a [`Scalar`]: rigid-body kinematics is mostly
//! constant geometry (joint origins, axes) times a few joint-dependent values, and on Burn
//! tensors every operation allocates. Arithmetic on constants happens in f64, a product with
//! 0 or 1 costs nothing, and a constant enters a scalar expression as `scale` or `shift`.

use std::ops::{Add, Mul, Neg, Sub};

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

    pub fn cos(&self) -> Self {
        match self {
            C(c) => C(c.cos()),
            V(x) => V(x.cos()),
        }
    }

    pub fn sin(&self) -> Self {
        match self {
            C(c) => C(c.sin()),
            V(x) => V(x.sin()),
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

pub type Vec3<S> = [Term<S>; 3];
pub type Mat3<S> = [[Term<S>; 3]; 3];

pub fn constant_vec<S>(v: [f64; 3]) -> Vec3<S> {
    v.map(C)
}

pub fn constant_mat<S>(m: [[f64; 3]; 3]) -> Mat3<S> {
    m.map(|r| r.map(C))
}

/// Σ_k a_k b_k.
fn dot3<S: Scalar>(a: [&Term<S>; 3], b: [&Term<S>; 3]) -> Term<S> {
    (a[0].clone() * b[0].clone()) + (a[1].clone() * b[1].clone()) + (a[2].clone() * b[2].clone())
}

pub fn dot<S: Scalar>(a: &Vec3<S>, b: &Vec3<S>) -> Term<S> {
    dot3([&a[0], &a[1], &a[2]], [&b[0], &b[1], &b[2]])
}

pub fn add<S: Scalar>(a: &Vec3<S>, b: &Vec3<S>) -> Vec3<S> {
    std::array::from_fn(|i| a[i].clone() + b[i].clone())
}

pub fn sub<S: Scalar>(a: &Vec3<S>, b: &Vec3<S>) -> Vec3<S> {
    std::array::from_fn(|i| a[i].clone() - b[i].clone())
}

pub fn scale<S: Scalar>(a: &Vec3<S>, s: &Term<S>) -> Vec3<S> {
    std::array::from_fn(|i| a[i].clone() * s.clone())
}

pub fn cross<S: Scalar>(a: &Vec3<S>, b: &Vec3<S>) -> Vec3<S> {
    let c = |i: usize, j: usize| a[i].clone() * b[j].clone() - a[j].clone() * b[i].clone();
    [c(1, 2), c(2, 0), c(0, 1)]
}

/// A b.
pub fn mat_vec<S: Scalar>(a: &Mat3<S>, b: &Vec3<S>) -> Vec3<S> {
    std::array::from_fn(|i| dot(&a[i], b))
}

/// Aᵀ b.
pub fn mat_t_vec<S: Scalar>(a: &Mat3<S>, b: &Vec3<S>) -> Vec3<S> {
    std::array::from_fn(|i| dot3([&a[0][i], &a[1][i], &a[2][i]], [&b[0], &b[1], &b[2]]))
}

/// A B.
pub fn mat_mul<S: Scalar>(a: &Mat3<S>, b: &Mat3<S>) -> Mat3<S> {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            dot3(
                [&a[i][0], &a[i][1], &a[i][2]],
                [&b[0][j], &b[1][j], &b[2][j]],
            )
        })
    })
}

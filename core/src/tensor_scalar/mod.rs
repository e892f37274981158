//! Burn's float tensors as the mechanics' scalars (only with the `burn` feature, which the
//! service turns on and the C library leaves off): a `[batch, 1]` column is a `Scalar`, a
//! `StateVec` and a trainable `Coef`, so the one assembly and integrator written over
//! `Scalar` also run on a training batch. The impls live here because Rust lets a trait be
//! implemented for a foreign type only in the trait's own crate.

mod tanh;

use burn::tensor::Tensor;

use crate::physics::assembly;
use crate::physics::integrator::StateVec;
use crate::physics::scalar::Scalar;
pub use tanh::tanh;

/// Trainable values in training: `[1, 1]` tensors, tracked.
impl assembly::Coef<Tensor<2>> for Tensor<2> {
    fn times(&self, x: &Tensor<2>) -> Tensor<2> {
        x.clone() * self.clone()
    }
    fn value(&self, _like: &Tensor<2>) -> Tensor<2> {
        self.clone()
    }
    fn mul_div(&self, mul: f64, div: f64) -> Self {
        self.clone().mul_scalar(mul / div)
    }
}

/// A Burn float tensor used as a scalar column: `[batch, 1]` for per-sample values, `[1, 1]`
/// for parameters (broadcast against the batch).
impl Scalar for Tensor<2> {
    fn cos(&self) -> Self {
        self.clone().cos()
    }
    fn sin(&self) -> Self {
        self.clone().sin()
    }
    fn sqrt(&self) -> Self {
        self.clone().sqrt()
    }
    fn exp(&self) -> Self {
        self.clone().exp()
    }
    fn ln(&self) -> Self {
        self.clone().log()
    }
    fn atan2(&self, x: &Self) -> Self {
        self.clone().atan2(x.clone())
    }
    fn sigmoid(&self) -> Self {
        burn::tensor::activation::sigmoid(self.clone())
    }
    fn softplus(&self) -> Self {
        // The same overflow-free form as the f64 impl, so both paths agree to rounding
        // (Burn's own softplus switches to the identity above a threshold).
        self.clone().clamp_min(0.0) + self.clone().abs().neg().exp().log1p()
    }
    fn scale(&self, c: f64) -> Self {
        self.clone().mul_scalar(c)
    }
    fn shift(&self, c: f64) -> Self {
        self.clone().add_scalar(c)
    }
    fn square(&self) -> Self {
        self.clone().square()
    }
    fn tanh(&self) -> Self {
        tanh::tanh(self.clone())
    }
    fn lift(&self, c: f64) -> Self {
        self.full_like(c)
    }
}

impl StateVec for Tensor<2> {
    fn axpy(&self, a: f64, x: &Self) -> Self {
        self.clone() + x.clone().mul_scalar(a)
    }
}

//! The number type the model's equations are written over.
//!
//! Templates, the Cholesky factorization, the Coriolis term and the triangular solves are
//! written once, generically over [`Scalar`], and run on
//! - `f64` (simulation, reference checks, the f64 inference path),
//! - the training tape's [`Var`](super::tape::Var), a column of a block's rows (reverse mode
//!   differentiates w.r.t. θ),
//! - [`Dual`](super::dual::Dual) numbers over either, which give the input derivatives
//!   ∂/∂q in forward mode (so that training's one reverse pass also differentiates them,
//!   docs/dynamics.md#forward-mode-input-derivatives).

use super::tangents::{Sparse, Tangents, WIDTH};
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// `'static`: every number type owns its values (what lets f64 callers share a thread's
/// multibody workspace, `multibody::thread_data::with_workspace`).
///
/// The operators in place (`a += &b`) give what `a = a + b` gives, to the bit; they exist
/// for wide values (a dual number over a `Pack` of 64 states is ~1.5 kB), which the
/// by-value operators copy several times per operation.
pub trait Scalar:
    'static
    + Clone
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + for<'a> AddAssign<&'a Self>
    + for<'a> SubAssign<&'a Self>
    + for<'a> MulAssign<&'a Self>
    + for<'a> DivAssign<&'a Self>
{
    /// Where a dual number over this scalar keeps its tangents (`Dual<S>`), which sets how
    /// many directions a group holds ([`groups`](super::dual::groups)): a wide scalar (a
    /// `Pack` of 32 states) keeps fewer, since every operation moves all its slots.
    type Tangents: Tangents<Self>;
    fn cos(&self) -> Self;
    fn sin(&self) -> Self;
    fn sqrt(&self) -> Self;
    fn exp(&self) -> Self;
    /// Natural logarithm.
    fn ln(&self) -> Self;
    /// The angle of (x, y) = (`x`, self), in (−π, π].
    fn atan2(&self, x: &Self) -> Self;
    /// Logistic sigmoid, the derivative of softplus.
    fn sigmoid(&self) -> Self;
    /// ln(1 + eˣ), computed without overflow.
    fn softplus(&self) -> Self;
    /// c · self.
    fn scale(&self, c: f64) -> Self;
    /// self + c.
    fn shift(&self, c: f64) -> Self;
    fn square(&self) -> Self {
        let mut s = self.clone();
        s *= self;
        s
    }
    fn tanh(&self) -> Self;
    /// The constant `c` as a value of the same kind (and shape) as `self`.
    fn lift(&self, c: f64) -> Self;
}

impl Scalar for f64 {
    type Tangents = Sparse<f64, WIDTH>;
    fn cos(&self) -> Self {
        f64::cos(*self)
    }
    fn sin(&self) -> Self {
        f64::sin(*self)
    }
    fn sqrt(&self) -> Self {
        f64::sqrt(*self)
    }
    fn exp(&self) -> Self {
        f64::exp(*self)
    }
    fn ln(&self) -> Self {
        f64::ln(*self)
    }
    fn atan2(&self, x: &Self) -> Self {
        f64::atan2(*self, *x)
    }
    fn sigmoid(&self) -> Self {
        1.0 / (1.0 + (-self).exp())
    }
    fn softplus(&self) -> Self {
        // max(x, 0) + ln(1 + e^-|x|) never overflows.
        self.max(0.0) + (-self.abs()).exp().ln_1p()
    }
    fn scale(&self, c: f64) -> Self {
        c * self
    }
    fn shift(&self, c: f64) -> Self {
        self + c
    }
    fn tanh(&self) -> Self {
        f64::tanh(*self)
    }
    fn lift(&self, c: f64) -> Self {
        c
    }
}

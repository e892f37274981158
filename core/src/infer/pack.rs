//! A coordinate of N states as one number. A batch's structure (Cholesky factor, Coriolis
//! term, solve, a formula template's expressions) runs a pack of states at a time: each
//! operation of the generic equations is one loop over its lanes, so a formula's
//! interpretation and a dual number's bookkeeping are paid once per pack (a 3000-term
//! potential's energy report ran ~10× longer state by state), with no heap: a `Pack` is
//! `Copy`, and so is everything built of it.
//!
//! Two widths. A batch's whole units (`workspace::UNIT_ROWS`) run in packs of 64: the
//! white-box cartpole's and formula double pendulum's Predict of 1024 states took 1.1–1.15×
//! as long in packs of 32, and 1.4× / 1.0× in packs of 128 (in units of 128 rows). A
//! remainder runs in packs of 16, since a pack computes all its lanes whether or not they
//! hold a state: iLQR plans, whose line search steps 10 states at a time, took 1.5–1.8× as
//! long with those in one pack of 64. Values this wide are copied by every by-value operation, so the hot loops use the
//! operators in place (`a *= &b`).
//!
//! Every operation is f64's own, lane by lane: a batch gives the same numbers, bit for bit,
//! as its states one at a time.

use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use crate::physics::scalar::Scalar;
use crate::physics::tangents::Sparse;

/// States per pack of a batch's whole units (`workspace::UNIT_ROWS`).
pub const PACK: usize = 64;

/// States per pack of a batch's remainder (a unit of fewer rows: the 10 step sizes of a
/// plan's line search, a collocation's last knots).
pub const NARROW: usize = 16;

/// The directions a dual number over a `Pack` carries (`Scalar::Tangents`): every
/// operation moves all its slots, so as few as a white-box template of n = 2 needs in one
/// pass (eight slots made the same Predicts 1.2–1.5× slower).
const DIRS: usize = 2;

/// One coordinate of N states ([`PACK`] or [`NARROW`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pack<const N: usize = PACK>(pub [f64; N]);

impl<const N: usize> Pack<N> {
    fn map(&self, f: impl Fn(f64) -> f64) -> Self {
        Pack(std::array::from_fn(|k| f(self.0[k])))
    }

    fn zip(&self, o: &Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Pack(std::array::from_fn(|k| f(self.0[k], o.0[k])))
    }
}

/// `a ∘ b` and `a ∘= &b`, lane by lane.
macro_rules! lanewise {
    ($trait:ident, $method:ident, $assign:ident, $assign_method:ident, $op:tt) => {
        impl<const N: usize> $trait for Pack<N> {
            type Output = Self;
            fn $method(mut self, o: Self) -> Self {
                self.$assign_method(&o);
                self
            }
        }
        impl<const N: usize> $assign<&Self> for Pack<N> {
            fn $assign_method(&mut self, o: &Self) {
                for (a, b) in self.0.iter_mut().zip(&o.0) {
                    *a = *a $op *b;
                }
            }
        }
    };
}

lanewise!(Add, add, AddAssign, add_assign, +);
lanewise!(Sub, sub, SubAssign, sub_assign, -);
lanewise!(Mul, mul, MulAssign, mul_assign, *);
lanewise!(Div, div, DivAssign, div_assign, /);

impl<const N: usize> Neg for Pack<N> {
    type Output = Self;
    fn neg(self) -> Self {
        self.map(|v| -v)
    }
}

impl<const N: usize> Scalar for Pack<N> {
    /// Two directions a group: a white-box template's ∂/∂q of n = 2 in one pass, and a
    /// dual number of 200 bytes rather than the 650 that eight slots of a `Pack` take.
    type Tangents = Sparse<Self, DIRS>;
    fn cos(&self) -> Self {
        self.map(f64::cos)
    }
    fn sin(&self) -> Self {
        self.map(f64::sin)
    }
    fn sqrt(&self) -> Self {
        self.map(f64::sqrt)
    }
    fn exp(&self) -> Self {
        self.map(f64::exp)
    }
    fn ln(&self) -> Self {
        self.map(f64::ln)
    }
    fn atan2(&self, x: &Self) -> Self {
        self.zip(x, f64::atan2)
    }
    fn sigmoid(&self) -> Self {
        self.map(|v| Scalar::sigmoid(&v))
    }
    fn softplus(&self) -> Self {
        self.map(|v| Scalar::softplus(&v))
    }
    fn scale(&self, c: f64) -> Self {
        self.map(|v| Scalar::scale(&v, c))
    }
    fn shift(&self, c: f64) -> Self {
        self.map(|v| Scalar::shift(&v, c))
    }
    fn tanh(&self) -> Self {
        self.map(f64::tanh)
    }
    fn lift(&self, c: f64) -> Self {
        Pack([c; N])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pack_computes_each_lane_as_f64_does() {
        // Lane by lane the same f64 operations in the same order: equality is bitwise.
        let a = Pack(std::array::from_fn(|k| 0.3 - 0.4 * k as f64));
        let b = Pack(std::array::from_fn(|k| 1.7 + 0.25 * k as f64));
        let f = |x: Pack, y: Pack| {
            let z = (x * y.sin() - y.exp()) / x.cos();
            z.softplus().sqrt() + z.sigmoid().scale(2.0).shift(-1.0) + x.atan2(&y).tanh()
        };
        let g = |x: f64, y: f64| {
            let z = (x * y.sin() - y.exp()) / x.cos();
            Scalar::softplus(&z).sqrt()
                + Scalar::shift(&Scalar::scale(&Scalar::sigmoid(&z), 2.0), -1.0)
                + x.atan2(y).tanh()
        };
        let got = f(a, b);
        for k in 0..PACK {
            assert_eq!(got.0[k].to_bits(), g(a.0[k], b.0[k]).to_bits(), "lane {k}");
        }
        assert_eq!(-a.lift(2.0), Pack([-2.0; PACK]));
    }
}

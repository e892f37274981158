//! The number types the evaluator computes on, each one coordinate of a whole batch.
//!
//! A batch runs through the model's structure (Cholesky factor, Coriolis term, solve,
//! integrator) once, as columns: [`Col`] holds one coordinate of every sample contiguously,
//! so each operation of the generic equations is one loop over the batch instead of a
//! per-sample walk through dual numbers (which cost more than the networks at 1024 states).
//! A single state uses plain `f64` instead, where a column's allocation per operation would
//! be the cost. Dual numbers over either carry the directions a linearization differentiates
//! in ("outer" tangents, see [`Activations`]).

use std::ops::{Add, Div, Mul, Neg, Sub};

use super::activations::Activations;
use crate::physics::dual::{Dense, Dual, Sparse, Tangents, WIDTH};
use crate::physics::scalar::Scalar;

/// One coordinate of every sample in a batch.
#[derive(Debug, Clone, PartialEq)]
pub struct Col(pub Vec<f64>);

impl Col {
    /// Elementwise `f(self, o)`, in place: operations consume their operands, so a chain of
    /// them allocates only where the generic code clones.
    fn zip(mut self, o: &Col, f: impl Fn(f64, f64) -> f64) -> Col {
        debug_assert_eq!(self.0.len(), o.0.len(), "columns of one batch");
        for (a, &b) in self.0.iter_mut().zip(&o.0) {
            *a = f(*a, b);
        }
        self
    }

    fn map(&self, f: impl Fn(f64) -> f64) -> Col {
        Col(self.0.iter().map(|&v| f(v)).collect())
    }
}

impl Add for Col {
    type Output = Col;
    fn add(self, o: Col) -> Col {
        self.zip(&o, |a, b| a + b)
    }
}

impl Sub for Col {
    type Output = Col;
    fn sub(self, o: Col) -> Col {
        self.zip(&o, |a, b| a - b)
    }
}

impl Mul for Col {
    type Output = Col;
    fn mul(self, o: Col) -> Col {
        self.zip(&o, |a, b| a * b)
    }
}

impl Div for Col {
    type Output = Col;
    fn div(self, o: Col) -> Col {
        self.zip(&o, |a, b| a / b)
    }
}

impl Neg for Col {
    type Output = Col;
    fn neg(mut self) -> Col {
        self.0.iter_mut().for_each(|v| *v = -*v);
        self
    }
}

/// Every function is f64's own, elementwise: a batch gives the same numbers as its samples
/// one at a time.
impl Scalar for Col {
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
        self.clone().zip(x, f64::atan2)
    }
    fn sigmoid(&self) -> Self {
        self.map(|v| Scalar::sigmoid(&v))
    }
    fn softplus(&self) -> Self {
        self.map(|v| Scalar::softplus(&v))
    }
    fn scale(&self, c: f64) -> Self {
        self.map(|v| c * v)
    }
    fn shift(&self, c: f64) -> Self {
        self.map(|v| v + c)
    }
    fn tanh(&self) -> Self {
        self.map(f64::tanh)
    }
    fn lift(&self, c: f64) -> Self {
        Col(vec![c; self.0.len()])
    }
}

/// A plain batch coordinate: `f64` (a batch of one) or [`Col`].
pub trait Column: Scalar {
    /// How a dual number over this column keeps the outer (linearization) directions'
    /// tangents: dense for one state, where within a step every value soon depends on every
    /// direction (an MVF's Linearize on the UR5: 2.2× faster than sparse ones, whose
    /// per-operation copies of unused slots dominated), sparse for a batch's columns, where
    /// a missing tangent saves a whole column's arithmetic.
    type Tangents: Tangents<Self>;
    fn rows(&self) -> usize;
    /// Sample b's value.
    fn get(&self, b: usize) -> f64;
    /// Coordinate j of row-major `[B, width]` samples.
    fn gather(rows: &[f64], width: usize, j: usize) -> Self;
    /// Stores this coordinate as unit j of the jet's block (o, i).
    fn write_block(&self, jet: &mut Activations, o: usize, i: usize, j: usize);
    /// Unit j of the jet's block (o, i).
    fn read_block(jet: &Activations, o: usize, i: usize, j: usize) -> Self;
}

impl Column for f64 {
    type Tangents = Dense<WIDTH>;
    fn rows(&self) -> usize {
        1
    }
    fn get(&self, _: usize) -> f64 {
        *self
    }
    fn gather(rows: &[f64], width: usize, j: usize) -> Self {
        debug_assert_eq!(rows.len(), width, "one sample");
        rows[j]
    }
    fn write_block(&self, jet: &mut Activations, o: usize, i: usize, j: usize) {
        jet.set(o, i, 0, j, *self);
    }
    fn read_block(jet: &Activations, o: usize, i: usize, j: usize) -> Self {
        jet.at(o, i, 0, j)
    }
}

impl Column for Col {
    type Tangents = Sparse<Col, WIDTH>;
    fn rows(&self) -> usize {
        self.0.len()
    }
    fn get(&self, b: usize) -> f64 {
        self.0[b]
    }
    fn gather(rows: &[f64], width: usize, j: usize) -> Self {
        Col(rows.iter().skip(j).step_by(width).copied().collect())
    }
    fn write_block(&self, jet: &mut Activations, o: usize, i: usize, j: usize) {
        for (b, &v) in self.0.iter().enumerate() {
            jet.set(o, i, b, j, v);
        }
    }
    fn read_block(jet: &Activations, o: usize, i: usize, j: usize) -> Self {
        Col((0..jet.batch).map(|b| jet.at(o, i, b, j)).collect())
    }
}

/// What the evaluator runs on: a batch coordinate, alone or as a dual number whose tangents
/// are the outer directions.
pub trait Lanes: Scalar {
    fn rows(&self) -> usize;
    /// Outer directions carried.
    fn dirs(&self) -> usize;
    /// Stores this coordinate (value and outer tangents) as unit j of the jet's inner block
    /// i: the value of input j (i = 0) or its ∂/∂q_{i−1}.
    fn write(&self, jet: &mut Activations, i: usize, j: usize);
    /// Output unit j of the jet's inner block i, with its outer tangents.
    fn read(jet: &Activations, i: usize, j: usize) -> Self;
}

impl<C: Column> Lanes for C {
    fn rows(&self) -> usize {
        Column::rows(self)
    }
    fn dirs(&self) -> usize {
        0
    }
    fn write(&self, jet: &mut Activations, i: usize, j: usize) {
        self.write_block(jet, 0, i, j);
    }
    fn read(jet: &Activations, i: usize, j: usize) -> Self {
        C::read_block(jet, 0, i, j)
    }
}

impl<C: Column, T: Tangents<C>> Lanes for Dual<C, T> {
    fn rows(&self) -> usize {
        self.v.rows()
    }
    fn dirs(&self) -> usize {
        Dual::dirs(self)
    }
    fn write(&self, jet: &mut Activations, i: usize, j: usize) {
        self.v.write_block(jet, 0, i, j);
        // A missing tangent is zero, which the fresh jet already holds.
        for o in 0..Dual::dirs(self) {
            if let Some(t) = self.tangent(o) {
                t.write_block(jet, o + 1, i, j);
            }
        }
    }
    fn read(jet: &Activations, i: usize, j: usize) -> Self {
        Dual::new(
            C::read_block(jet, 0, i, j),
            (1..=jet.outer).map(|o| Some(C::read_block(jet, o, i, j))),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_operations_are_the_samples_operations() {
        // The batch path must reproduce the single-state path exactly (same f64 operations
        // in the same order), so equality here is bitwise.
        let a = Col(vec![0.3, -1.2, 2.5]);
        let b = Col(vec![1.7, 0.4, -0.9]);
        let f = |x: Col, y: Col| {
            ((x.clone() * y.sin() - y.exp()) / x.cos())
                .softplus()
                .sqrt()
        };
        let g = |x: f64, y: f64| ((x * y.sin() - y.exp()) / x.cos()).softplus().sqrt();
        let got = f(a.clone(), b.clone());
        for k in 0..3 {
            assert_eq!(
                got.0[k].to_bits(),
                g(a.0[k], b.0[k]).to_bits(),
                "sample {k}"
            );
        }
        assert_eq!(a.lift(2.0), Col(vec![2.0; 3]));
        let want: Vec<f64> = a.0.iter().map(|v| -(2.0 * (v + 1.0))).collect();
        assert_eq!(-a.shift(1.0).scale(2.0), Col(want));
    }
}

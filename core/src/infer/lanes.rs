//! The numbers the evaluator's structure runs on. A batch's networks run once over all its
//! states (matrix products); the structure then reads its states' rows of their outputs: a
//! pack of plain states at a time as a [`Pack`], or one state as a dual number whose tangents are the
//! directions a linearization differentiates in ("outer" tangents, see [`Activations`]),
//! dense and inline (`Jet`) because within a step every value soon depends on every
//! direction.

use super::activations::Activations;
use super::pack::Pack;
use crate::physics::dual::{Dual, Tangents};
use crate::physics::scalar::Scalar;

/// What the evaluator runs on: states' coordinates, alone, N at once, or with their
/// outer tangents.
pub trait Lanes: Scalar {
    /// What the structure runs a group of N of these on: N states' f64 coordinates as a
    /// `Pack<N>`; a value that already stands for its group (a pack, a dual number), itself.
    type Group<const N: usize>: Lanes;
    /// Whether N of these make a group, or each is a group of its own.
    const GROUPS: bool;
    /// Outer directions carried.
    fn dirs(&self) -> usize;
    /// Stores this coordinate (value and outer tangents) as unit j of state b (and the states
    /// after it that it holds) in the jet's inner block i: the value of input j (i = 0) or its
    /// ∂/∂q_{i−1}.
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize);
    /// Output unit j of state b (and the states after it that this holds, the batch's last
    /// again past its end) in the jet's inner block i, with its outer tangents.
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self;
    /// A group from its states' values: `lane(k)` for k < N.
    fn group<const N: usize>(lane: impl Fn(usize) -> Self) -> Self::Group<N>;
    /// State k of a group.
    fn lane<const N: usize>(group: &Self::Group<N>, k: usize) -> Self;
}

impl Lanes for f64 {
    type Group<const N: usize> = Pack<N>;
    const GROUPS: bool = true;
    fn dirs(&self) -> usize {
        0
    }
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize) {
        jet.set(0, i, b, j, *self);
    }
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self {
        jet.at(0, i, b, j)
    }
    fn group<const N: usize>(lane: impl Fn(usize) -> Self) -> Pack<N> {
        Pack(std::array::from_fn(lane))
    }
    fn lane<const N: usize>(group: &Pack<N>, k: usize) -> Self {
        group.0[k]
    }
}

impl<const M: usize> Lanes for Pack<M> {
    type Group<const N: usize> = Self;
    const GROUPS: bool = false;
    fn dirs(&self) -> usize {
        0
    }
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize) {
        for (k, &v) in self.0.iter().enumerate().take(jet.batch.saturating_sub(b)) {
            jet.set(0, i, b + k, j, v);
        }
    }
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self {
        Pack(std::array::from_fn(|k| {
            jet.at(0, i, (b + k).min(jet.batch - 1), j)
        }))
    }
    fn group<const N: usize>(lane: impl Fn(usize) -> Self) -> Self {
        lane(0)
    }
    fn lane<const N: usize>(group: &Self, _: usize) -> Self {
        *group
    }
}

impl<T: Tangents<f64>> Lanes for Dual<f64, T> {
    type Group<const N: usize> = Self;
    const GROUPS: bool = false;
    fn dirs(&self) -> usize {
        Dual::dirs(self)
    }
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize) {
        jet.set(0, i, b, j, self.v);
        // A missing tangent is zero, which the fresh jet already holds.
        for o in 0..Dual::dirs(self) {
            if let Some(&t) = self.tangent(o) {
                jet.set(o + 1, i, b, j, t);
            }
        }
    }
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self {
        Dual::new(
            jet.at(0, i, b, j),
            (1..=jet.outer).map(|o| Some(jet.at(o, i, b, j))),
        )
    }
    fn group<const N: usize>(lane: impl Fn(usize) -> Self) -> Self {
        lane(0)
    }
    fn lane<const N: usize>(group: &Self, _: usize) -> Self {
        group.clone()
    }
}

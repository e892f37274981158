//! The numbers the evaluator's structure runs on. A batch's networks run once over all its
//! states (matrix products); the structure then reads its states' rows of their outputs: 64
//! plain states at a time as a [`Pack`], or one state as a dual number whose tangents are the
//! directions a linearization differentiates in ("outer" tangents, see [`Activations`]),
//! dense and inline (`Jet`) because within a step every value soon depends on every
//! direction.

use super::activations::Activations;
use super::pack::{PACK, Pack};
use crate::physics::dual::{Dual, Tangents};
use crate::physics::scalar::Scalar;

/// What the evaluator runs on: states' coordinates, alone, 64 at once, or with their
/// outer tangents.
pub trait Lanes: Scalar {
    /// What the structure runs a group of these on, and how many states a group holds.
    type Group: Lanes;
    const GROUP: usize;
    /// Outer directions carried.
    fn dirs(&self) -> usize;
    /// Stores this coordinate (value and outer tangents) as unit j of state b (and the states
    /// after it that it holds) in the jet's inner block i: the value of input j (i = 0) or its
    /// ∂/∂q_{i−1}.
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize);
    /// Output unit j of state b (and the states after it that this holds, the batch's last
    /// again past its end) in the jet's inner block i, with its outer tangents.
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self;
    /// A group from its states' values: `lane(k)` for k < GROUP.
    fn group(lane: impl Fn(usize) -> Self) -> Self::Group;
    /// State k of a group.
    fn lane(group: &Self::Group, k: usize) -> Self;
}

impl Lanes for f64 {
    type Group = Pack;
    const GROUP: usize = PACK;
    fn dirs(&self) -> usize {
        0
    }
    fn write(&self, jet: &mut Activations, b: usize, i: usize, j: usize) {
        jet.set(0, i, b, j, *self);
    }
    fn read(jet: &Activations, b: usize, i: usize, j: usize) -> Self {
        jet.at(0, i, b, j)
    }
    fn group(lane: impl Fn(usize) -> Self) -> Pack {
        Pack(std::array::from_fn(lane))
    }
    fn lane(group: &Pack, k: usize) -> Self {
        group.0[k]
    }
}

impl Lanes for Pack {
    type Group = Pack;
    const GROUP: usize = 1;
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
    fn group(lane: impl Fn(usize) -> Self) -> Pack {
        lane(0)
    }
    fn lane(group: &Pack, _: usize) -> Self {
        *group
    }
}

impl<T: Tangents<f64>> Lanes for Dual<f64, T> {
    type Group = Self;
    const GROUP: usize = 1;
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
    fn group(lane: impl Fn(usize) -> Self) -> Self {
        lane(0)
    }
    fn lane(group: &Self, _: usize) -> Self {
        group.clone()
    }
}

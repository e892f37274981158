//! Where a dual number keeps its tangents ([`Tangents`]): the storage its rules
//! (`physics::dual`) are written over, and which each scalar names for its own dual numbers
//! (`Scalar::Tangents`). Apart from `dual` so that `scalar` can name them without a circle.

use arrayvec::ArrayVec;

/// Where a dual number keeps its tangents: the operations its rules are written with.
pub trait Tangents<S>: Clone + 'static {
    /// The most directions it holds.
    const WIDTH: usize;
    /// No tangent: a constant.
    fn none() -> Self;
    /// Tangents of directions 0, 1, … in order; `None` is a zero.
    fn from_options(t: impl IntoIterator<Item = Option<S>>) -> Self;
    /// Direction k's tangent; `None` is a zero.
    fn get(&self, k: usize) -> Option<&S>;
    /// How many directions may carry a tangent: every one beyond is zero.
    fn dirs(&self) -> usize;
    /// Whether a function of this value is a constant without computing its tangents.
    fn is_none(&self) -> bool;
    /// `f` of each tangent.
    fn map(&self, f: impl Fn(&S) -> S) -> Self;
    /// `f` of each tangent, consuming them.
    fn map_owned(self, f: impl Fn(S) -> S) -> Self;
    /// `f` of each direction's pair of tangents, `None` where it gives a zero.
    fn zip(&self, o: &Self, f: impl Fn(Option<&S>, Option<&S>) -> Option<S>) -> Self;
    /// `f` on each direction's tangent in place (`None` a zero, which `f` may fill), given
    /// the other's.
    fn update(&mut self, o: &Self, f: impl FnMut(&mut Option<S>, Option<&S>));
}

/// At most N optional tangents, only those in use initialized.
#[derive(Debug, Clone)]
pub struct Sparse<S, const N: usize>(ArrayVec<Option<S>, N>);

impl<S: Clone + 'static, const N: usize> Tangents<S> for Sparse<S, N> {
    const WIDTH: usize = N;
    fn none() -> Self {
        Self(ArrayVec::new())
    }
    fn from_options(t: impl IntoIterator<Item = Option<S>>) -> Self {
        let mut out = ArrayVec::new();
        for t in t {
            assert!(!out.is_full(), "a dual number of {N} directions given more");
            out.push(t);
        }
        Self(out)
    }
    fn get(&self, k: usize) -> Option<&S> {
        self.0.get(k).and_then(Option::as_ref)
    }
    fn dirs(&self) -> usize {
        self.0.len()
    }
    fn is_none(&self) -> bool {
        self.0.iter().all(Option::is_none)
    }
    fn map(&self, f: impl Fn(&S) -> S) -> Self {
        Self(self.0.iter().map(|t| t.as_ref().map(&f)).collect())
    }
    fn map_owned(self, f: impl Fn(S) -> S) -> Self {
        Self(self.0.into_iter().map(|t| t.map(&f)).collect())
    }
    fn zip(&self, o: &Self, f: impl Fn(Option<&S>, Option<&S>) -> Option<S>) -> Self {
        let n = self.0.len().max(o.0.len());
        Self((0..n).map(|k| f(self.get(k), o.get(k))).collect())
    }
    fn update(&mut self, o: &Self, mut f: impl FnMut(&mut Option<S>, Option<&S>)) {
        while self.0.len() < o.0.len() {
            self.0.push(None);
        }
        for (k, t) in self.0.iter_mut().enumerate() {
            f(t, o.get(k));
        }
    }
}

/// N tangents of f64, every one present.
#[derive(Debug, Clone, Copy)]
pub struct Dense<const N: usize>(pub(super) [f64; N]);

impl<const N: usize> Tangents<f64> for Dense<N> {
    const WIDTH: usize = N;
    fn none() -> Self {
        Self([0.0; N])
    }
    fn from_options(t: impl IntoIterator<Item = Option<f64>>) -> Self {
        let mut out = [0.0; N];
        for (k, t) in t.into_iter().enumerate() {
            assert!(k < N, "a dual number of {N} directions given more");
            out[k] = t.unwrap_or(0.0);
        }
        Self(out)
    }
    fn get(&self, k: usize) -> Option<&f64> {
        self.0.get(k)
    }
    fn dirs(&self) -> usize {
        self.0.iter().rposition(|&t| t != 0.0).map_or(0, |k| k + 1)
    }
    /// Never: checking every tangent would cost what computing them does.
    fn is_none(&self) -> bool {
        false
    }
    fn map(&self, f: impl Fn(&f64) -> f64) -> Self {
        Self(self.0.map(|t| f(&t)))
    }
    fn map_owned(self, f: impl Fn(f64) -> f64) -> Self {
        Self(self.0.map(f))
    }
    fn zip(&self, o: &Self, f: impl Fn(Option<&f64>, Option<&f64>) -> Option<f64>) -> Self {
        Self(std::array::from_fn(|k| {
            f(Some(&self.0[k]), Some(&o.0[k])).unwrap_or(0.0)
        }))
    }
    fn update(&mut self, o: &Self, mut f: impl FnMut(&mut Option<f64>, Option<&f64>)) {
        for (t, b) in self.0.iter_mut().zip(&o.0) {
            let mut a = Some(*t);
            f(&mut a, Some(b));
            *t = a.unwrap_or(0.0);
        }
    }
}

/// The directions a dual number carries by default (a linearization's 2n + m for the
/// templates' systems, a double pendulum's ∂/∂q twice over): a derivative in more directions
/// runs in groups of this many (`dual::groups`), each group's values computed again, which costs
/// less than tangents on the heap did and keeps every dual number a fixed size.
pub const WIDTH: usize = 8;

//! Windows of H consecutive transitions for multi-step training (docs/training.md#multi-step):
//! where they start, how their steps are weighted, and the check that the data has any.

use crate::data::Dataset;
use crate::data::trajectories::Segment;
use crate::error::{Error, Result};

/// The windows of one set of transitions: each starts at a row and spans `weights.len()`
/// transitions of one trajectory; step k's error counts with `weights[k]` (the weights sum
/// to 1, so a window's loss is a weighted mean over its steps).
#[derive(Debug, Clone, PartialEq)]
pub struct Windows {
    pub starts: Vec<usize>,
    pub weights: Vec<f64>,
}

impl Windows {
    /// Every row on its own: the one-step loss.
    pub fn one_step(count: usize) -> Self {
        Self {
            starts: (0..count).collect(),
            weights: vec![1.0],
        }
    }

    /// The windows of `horizon` transitions of `ds`'s trajectories, one starting at every row
    /// that has `horizon − 1` successors in its trajectory; none crosses a boundary.
    pub fn of(ds: &Dataset, horizon: usize, discount: f64) -> Self {
        if horizon == 1 {
            return Self::one_step(ds.count());
        }
        Self {
            starts: starts(&ds.segments(), horizon),
            weights: weights(horizon, discount),
        }
    }

    pub fn horizon(&self) -> usize {
        self.weights.len()
    }

    pub fn count(&self) -> usize {
        self.starts.len()
    }

    /// A bootstrap resample: as many windows, drawn from these with replacement.
    pub fn resample(&self, rng: &mut crate::rng::Rng) -> Self {
        let n = self.count();
        Self {
            starts: (0..n).map(|_| self.starts[rng.below(n)]).collect(),
            weights: self.weights.clone(),
        }
    }
}

/// The rows where a window of `horizon` transitions fits inside its segment.
pub fn starts(segments: &[Segment], horizon: usize) -> Vec<usize> {
    segments
        .iter()
        .filter(|s| s.length >= horizon)
        .flat_map(|s| s.start..=s.start + s.length - horizon)
        .collect()
}

/// γ^k / Σ_j γ^j for k = 0 .. horizon − 1.
pub fn weights(horizon: usize, discount: f64) -> Vec<f64> {
    let raw: Vec<f64> = (0..horizon).map(|k| discount.powi(k as i32)).collect();
    let total: f64 = raw.iter().sum();
    raw.into_iter().map(|w| w / total).collect()
}

/// Training on windows of `horizon` needs a trajectory at least that long: an error naming
/// `training.horizon` and the longest there is.
pub fn check(ds: &Dataset, horizon: usize) -> Result<()> {
    if horizon == 1 {
        return Ok(());
    }
    check_longest(
        ds.segments().iter().map(|s| s.length).max().unwrap_or(0),
        horizon,
    )
}

/// [`check`] given the longest trajectory (or a bound on it, known without the rows).
pub fn check_longest(longest: usize, horizon: usize) -> Result<()> {
    if horizon <= 1 || longest >= horizon {
        return Ok(());
    }
    Err(Error::invalid(
        "training.horizon",
        format!(
            "windows of {horizon} transitions need a trajectory of at least {horizon}, but the \
             longest in the training data is {longest} (upload trajectories, or flat rows in \
             time order whose next state is the following row's state)"
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::trajectories::from_lengths;

    #[test]
    fn windows_stay_inside_their_trajectory() {
        // Trajectories of 3, 1 and 4 transitions: rows 0-2, 3, 4-7.
        let segs = from_lengths(&[3, 1, 4]);
        assert_eq!(starts(&segs, 1), (0..8).collect::<Vec<_>>());
        assert_eq!(starts(&segs, 2), [0, 1, 4, 5, 6]);
        assert_eq!(starts(&segs, 3), [0, 4, 5]);
        assert_eq!(starts(&segs, 4), [4]);
        assert!(starts(&segs, 5).is_empty());
        // Every window's rows lie in one segment.
        for h in 1..=4 {
            for s in starts(&segs, h) {
                let seg = segs
                    .iter()
                    .find(|g| (g.start..g.start + g.length).contains(&s));
                let seg = seg.expect("a start inside a segment");
                assert!(s + h <= seg.start + seg.length, "h {h} start {s}");
            }
        }
    }

    #[test]
    fn weights_are_a_discounted_mean() {
        assert_eq!(weights(1, 0.5), [1.0]);
        assert_eq!(weights(4, 1.0), [0.25; 4]);
        let w = weights(3, 0.5);
        // 1, ½, ¼ over 1.75.
        let expect = [1.0 / 1.75, 0.5 / 1.75, 0.25 / 1.75];
        for (a, b) in w.iter().zip(expect) {
            assert!((a - b).abs() < 1e-15);
        }
    }
}

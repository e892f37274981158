//! Transition datasets (q, q̇, u → q', q̇'): validation and splits here, the file formats in
//! `formats.rs`, the sanity warnings in `sanity.rs`.

mod formats;
pub mod log;
mod sanity;
pub mod trajectories;

pub use sanity::{ACCEL_RMS_MAX, SPAN_MAX, VELOCITY_MISMATCH_MAX};

use crate::error::{Error, Result};
use crate::rng::Rng;

/// Row-major arrays of `count` transitions.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The step: every transition's, or with `steps` their median (the model's Δt).
    pub dt: f64,
    /// Configuration values per row (q, q_next).
    pub nq: usize,
    /// Velocities per row (qdot, qdot_next): nq unless a joint's configuration is not its
    /// velocity (a rotation kept as a unit complex number, docs/dynamics.md#configuration-space).
    pub nv: usize,
    pub m: usize,
    pub q: Vec<f64>,
    pub qdot: Vec<f64>,
    pub u: Vec<f64>,
    pub q_next: Vec<f64>,
    pub qdot_next: Vec<f64>,
    /// The transitions' count per trajectory when the data came in trajectory form (rows in
    /// order, summing to `count`); `None` for flat rows, whose trajectories are their chains
    /// (`segments`).
    pub trajectories: Option<Vec<usize>>,
    /// Each transition's own Δt when they differ (a robot's log kept on its samples' times:
    /// `with_steps`); `None`: every one is `dt`.
    pub steps: Option<Vec<f64>>,
}

pub const FIELDS: [&str; 5] = ["q", "qdot", "u", "q_next", "qdot_next"];

/// The sampling intervals graybox accepts, in seconds. Below 10 µs the one-step differences
/// q' − q drown in f32 rounding during training; above 10 s one RK4 step of a mechanical
/// system says nothing about its dynamics. A Δt outside this range has always been a unit or
/// export error (a reported 1e-320 produced a model with NaN scalings).
pub const DT_RANGE: (f64, f64) = (1e-5, 10.0);

impl Dataset {
    /// Configuration values per row (q, q_next).
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// Velocities per row (qdot, qdot_next).
    pub fn nv(&self) -> usize {
        self.nv
    }

    pub fn count(&self) -> usize {
        self.q.len().checked_div(self.nq).unwrap_or(0)
    }

    /// Builds a dataset from row-major arrays of (nq, nv) widths, checking every invariant.
    pub fn new(dt: f64, (nq, nv): (usize, usize), m: usize, arrays: [Vec<f64>; 5]) -> Result<Self> {
        let [q, qdot, u, q_next, qdot_next] = arrays;
        let d = Dataset {
            dt,
            nq,
            nv,
            m,
            q,
            qdot,
            u,
            q_next,
            qdot_next,
            trajectories: None,
            steps: None,
        };
        d.validate()?;
        Ok(d)
    }

    /// The same rows, each transition `steps[i]` seconds long (in `DT_RANGE`); `dt` becomes
    /// their median. Steps all equal to `dt` leave the dataset as it was (no `steps`).
    pub fn with_steps(mut self, steps: Vec<f64>) -> Result<Self> {
        if steps.len() != self.count() {
            return Err(Error::invalid(
                "dt",
                format!("has {} steps for {} transitions", steps.len(), self.count()),
            ));
        }
        let (lo, hi) = DT_RANGE;
        if let Some(i) = steps
            .iter()
            .position(|s| !(s.is_finite() && (lo..=hi).contains(s)))
        {
            return Err(Error::invalid(
                format!("dt[{i}]"),
                format!(
                    "must be a number of seconds in [{lo:e}, {hi}], got {}",
                    steps[i]
                ),
            ));
        }
        if steps.iter().all(|&s| s == self.dt) {
            return Ok(self);
        }
        self.dt = median(&steps);
        self.steps = Some(steps);
        Ok(self)
    }

    /// Transition `i`'s Δt.
    pub fn step(&self, i: usize) -> f64 {
        self.steps.as_ref().map_or(self.dt, |s| s[i])
    }

    /// The same rows as trajectories of `lengths` transitions each, in order.
    pub fn with_trajectories(mut self, lengths: Vec<usize>) -> Result<Self> {
        let total = lengths.iter().try_fold(0usize, |a, &l| a.checked_add(l));
        if total != Some(self.count()) {
            return Err(Error::invalid(
                "trajectories",
                format!(
                    "the lengths sum to {} but there are {} transitions",
                    total.map_or("more than usize".into(), |t| t.to_string()),
                    self.count()
                ),
            ));
        }
        self.trajectories = Some(lengths);
        Ok(self)
    }

    /// The trajectories: as uploaded, else the chains of the rows (`trajectories::chains`).
    pub fn segments(&self) -> Vec<trajectories::Segment> {
        match &self.trajectories {
            Some(lengths) => trajectories::from_lengths(lengths),
            None => trajectories::chains(self),
        }
    }

    fn validate(&self) -> Result<()> {
        let (lo, hi) = DT_RANGE;
        if !(self.dt.is_finite() && (lo..=hi).contains(&self.dt)) {
            return Err(Error::invalid(
                "dt",
                format!(
                    "must be a number of seconds in [{lo:e}, {hi}], got {}",
                    self.dt
                ),
            ));
        }
        if self.nq == 0 || self.nv == 0 {
            let field = if self.nq == 0 { "q" } else { "qdot" };
            return Err(Error::invalid(
                field,
                "rows must have at least one coordinate",
            ));
        }
        if self.m == 0 {
            return Err(Error::invalid(
                "u",
                "rows must have at least one input (use a column of zeros for an unforced system)",
            ));
        }
        let count = self.count();
        if count == 0 {
            return Err(Error::invalid("q", "the dataset has no transitions"));
        }
        for (name, arr, width) in self.fields() {
            if arr.len() != count * width {
                return Err(Error::invalid(
                    name,
                    format!("expected {count} rows of {width}"),
                ));
            }
            if let Some(i) = arr.iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    format!("{name}[{}]", i / width),
                    format!("row {} has a non-finite value ({})", i / width, arr[i]),
                ));
            }
        }
        Ok(())
    }

    fn fields(&self) -> [(&'static str, &Vec<f64>, usize); 5] {
        [
            ("q", &self.q, self.nq),
            ("qdot", &self.qdot, self.nv),
            ("u", &self.u, self.m),
            ("q_next", &self.q_next, self.nq),
            ("qdot_next", &self.qdot_next, self.nv),
        ]
    }

    /// The transitions at `idx`, in that order.
    pub fn subset(&self, idx: &[usize]) -> Dataset {
        let take = |a: &[f64], w: usize| -> Vec<f64> {
            idx.iter()
                .flat_map(|&i| a[i * w..(i + 1) * w].iter().copied())
                .collect()
        };
        Dataset {
            dt: self.dt,
            nq: self.nq,
            nv: self.nv,
            m: self.m,
            q: take(&self.q, self.nq),
            qdot: take(&self.qdot, self.nv),
            u: take(&self.u, self.m),
            q_next: take(&self.q_next, self.nq),
            qdot_next: take(&self.qdot_next, self.nv),
            trajectories: None,
            steps: (self.steps.as_ref()).map(|s| idx.iter().map(|&i| s[i]).collect()),
        }
    }

    /// A seeded random split into (train, validation); validation gets round(fraction·count)
    /// transitions, at least one when fraction > 0 and count > 1.
    pub fn split(&self, fraction: f64, seed: u64) -> (Dataset, Dataset) {
        let count = self.count();
        let mut idx: Vec<usize> = (0..count).collect();
        Rng::derive(seed, 0x5_9117).shuffle(&mut idx);
        let mut n_val = (fraction * count as f64).round() as usize;
        if fraction > 0.0 && count > 1 {
            n_val = n_val.clamp(1, count - 1);
        }
        let (val, train) = idx.split_at(n_val.min(count));
        (self.subset(train), self.subset(val))
    }

    /// State rows x = [q, v] (count × (nq + nv)) and targets x' = [q', v'].
    pub fn states(&self) -> (Vec<f64>, Vec<f64>) {
        let join = |a: &[f64], b: &[f64]| -> Vec<f64> {
            a.chunks(self.nq)
                .zip(b.chunks(self.nv))
                .flat_map(|(x, y)| x.iter().chain(y).copied())
                .collect()
        };
        (
            join(&self.q, &self.qdot),
            join(&self.q_next, &self.qdot_next),
        )
    }
}

/// The median of a non-empty list (an even count's two middles averaged).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

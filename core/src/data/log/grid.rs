//! One trajectory of a log at chosen times (its samples' own, or an even grid): its states
//! from the local fit, each input its mean over a step.

use super::{Fit, Inputs, LogColumns, Stencil};

/// One trajectory's samples: times and the selected columns (q, then qdot if given, then u).
pub(super) struct Piece<'a> {
    pub(super) time: &'a [f64],
    pub(super) columns: Vec<&'a [f64]>,
}

/// One grid time's state [q, q̇].
type State = Vec<f64>;

impl Piece<'_> {
    /// The times of the states: every t₀ + k·dt up to the last sample (`dt` Some), or the
    /// samples' own.
    pub(super) fn times(&self, dt: Option<f64>) -> Vec<f64> {
        let Some(dt) = dt else {
            return self.time.to_vec();
        };
        let (t0, t1) = (self.time[0], self.time[self.time.len() - 1]);
        // Grid points up to the last sample, allowing for the rounding of k·dt.
        let count = ((t1 - t0) / dt * (1.0 + 1e-12)).floor() as usize + 1;
        (0..count).map(|k| t0 + k as f64 * dt).collect()
    }

    /// The states at `times` within the trajectory, or None when it has too few samples to
    /// fit. Velocities given are the fit's value of them (and checked against the positions'
    /// rate in `check`); else the positions' rate.
    pub(super) fn states_at(
        &self,
        cols: &LogColumns,
        fit: Fit,
        times: &[f64],
        check: &mut Check,
    ) -> Option<Vec<State>> {
        let nq = cols.q.len();
        if self.time.len() < fit.order + 1 {
            return None;
        }
        let states = (times.iter())
            .map(|&t| {
                let s = fit.stencil(self.time, t);
                check.delay(&s, self.time, t);
                let (q, rate): (Vec<f64>, Vec<f64>) =
                    self.columns[..nq].iter().map(|c| s.apply(c)).unzip();
                let qdot: Vec<f64> = if cols.qdot.is_empty() {
                    rate
                } else {
                    let given: Vec<f64> = (self.columns[nq..2 * nq].iter())
                        .map(|c| s.apply(c).0)
                        .collect();
                    check.add(&rate, &given);
                    given
                };
                if !cols.qddot.is_empty() {
                    let at = nq + cols.qdot.len();
                    let (q, given) = (&self.columns[..nq], &self.columns[at..at + nq]);
                    for (q, a) in q.iter().zip(given) {
                        check.add_acceleration(s.second_of(q), s.apply(a).0);
                    }
                }
                [q, qdot].concat()
            })
            .collect();
        Some(states)
    }

    /// The transitions between consecutive states (at `times`), each under its inputs' mean
    /// over the step (through `fit` first when it is given), appended to the dataset's
    /// arrays.
    pub(super) fn transitions(
        &self,
        states: &[State],
        (nq, m): (usize, usize),
        times: &[f64],
        (inputs_go, smooth): (Inputs, Option<Fit>),
        arrays: &mut [Vec<f64>; 5],
    ) {
        let inputs = &self.columns[self.columns.len() - m..];
        let smoothed = smooth.map(|fit| self.through_the_fit(inputs, times, (fit, inputs_go)));
        for (k, (pair, t)) in states.windows(2).zip(times.windows(2)).enumerate() {
            let (a, b) = (t[0], t[1]);
            arrays[0].extend_from_slice(&pair[0][..nq]);
            arrays[1].extend_from_slice(&pair[0][nq..]);
            match &smoothed {
                Some(s) => arrays[2].extend(s.iter().map(|u| u[k])),
                None => arrays[2]
                    .extend((inputs.iter()).map(|u| mean_over(self.time, u, (a, b), inputs_go))),
            }
            arrays[3].extend_from_slice(&pair[1][..nq]);
            arrays[4].extend_from_slice(&pair[1][nq..]);
        }
    }
}

impl Piece<'_> {
    /// Each input's mean over each step between `times` as the torque loss's accelerations
    /// see it: those are the fit's velocities differenced, v̂ = S[q] for the fit's rate S, so
    /// under M q̈ = u the efforts that balance them are S[W] differenced over the step, W = ∬u
    /// (the signal held or joined by straight lines as it `go`es, integrated exactly from the
    /// first sample). The same filter on both sides of the equation (parallel filtering)
    /// leaves M and the damping unbiased however much the fit smooths.
    fn through_the_fit(
        &self,
        inputs: &[&[f64]],
        times: &[f64],
        (fit, go): (Fit, Inputs),
    ) -> Vec<Vec<f64>> {
        let stencils: Vec<Stencil> = times.iter().map(|&t| fit.stencil(self.time, t)).collect();
        (inputs.iter())
            .map(|u| {
                let (mut once, mut twice) = (0.0, vec![0.0]);
                for (k, h) in self.time.windows(2).map(|w| w[1] - w[0]).enumerate() {
                    let (start, end) = match go {
                        Inputs::Linear => (u[k], u[k + 1]),
                        Inputs::Held => (u[k], u[k]),
                    };
                    twice.push(twice[k] + once * h + (2.0 * start + end) * h * h / 6.0);
                    once += 0.5 * (start + end) * h;
                }
                let rate: Vec<f64> = stencils.iter().map(|s| s.apply(&twice).1).collect();
                (rate.windows(2).zip(times.windows(2)))
                    .map(|(p, t)| (p[1] - p[0]) / (t[1] - t[0]))
                    .collect()
            })
            .collect()
    }
}

/// Sums of the velocity and acceleration checks' squared differences, and the fit's largest
/// delay.
#[derive(Default)]
pub(super) struct Check {
    sum: f64,
    count: usize,
    acceleration: (f64, usize),
    pub(super) lag: f64,
}

impl Check {
    /// The fit's delay at `t`: the centre of its value weights in time, relative to t. A fit
    /// that reproduces a straight line (order ≥ 1) has none, one-sided windows included; this
    /// measures it, rounding and all.
    fn delay(&mut self, s: &Stencil, times: &[f64], t: f64) {
        let centre: f64 = (s.value.iter().zip(&times[s.start..]))
            .map(|(w, tj)| w * (tj - t))
            .sum();
        self.lag = self.lag.max(centre.abs());
    }

    fn add(&mut self, estimated: &[f64], given: &[f64]) {
        for (a, b) in estimated.iter().zip(given) {
            self.sum += (a - b).powi(2);
            self.count += 1;
        }
    }

    fn add_acceleration(&mut self, estimated: f64, given: f64) {
        self.acceleration.0 += (estimated - given).powi(2);
        self.acceleration.1 += 1;
    }

    pub(super) fn rms(&self) -> Option<f64> {
        (self.count > 0).then(|| (self.sum / self.count as f64).sqrt())
    }

    pub(super) fn acceleration_rms(&self) -> Option<f64> {
        let (sum, count) = self.acceleration;
        (count > 0).then(|| (sum / count as f64).sqrt())
    }
}

/// The mean over [a, b] of the piecewise-linear signal through (times, y), held at its end
/// values outside them.
fn mean_over(times: &[f64], y: &[f64], (a, b): (f64, f64), go: Inputs) -> f64 {
    let at = |t: f64| -> f64 {
        let k = times.partition_point(|&s| s <= t);
        match k {
            0 => y[0],
            k if k == times.len() => y[k - 1],
            k => {
                let (t0, t1) = (times[k - 1], times[k]);
                y[k - 1] + (y[k] - y[k - 1]) * (t - t0) / (t1 - t0)
            }
        }
    };
    // A held value is the last sample's at or before t (the first's before it).
    let held = |t: f64| y[times.partition_point(|&s| s <= t).max(1) - 1];
    // The trapezoid rule is exact on each linear piece between the knots inside [a, b], the
    // midpoint rule on each constant one.
    let mut knots = vec![a];
    let first = times.partition_point(|&s| s <= a);
    knots.extend(times[first..].iter().copied().take_while(|&s| s < b));
    knots.push(b);
    let area: f64 = knots
        .windows(2)
        .map(|w| match go {
            Inputs::Linear => 0.5 * (at(w[0]) + at(w[1])) * (w[1] - w[0]),
            Inputs::Held => held(0.5 * (w[0] + w[1])) * (w[1] - w[0]),
        })
        .sum();
    area / (b - a)
}

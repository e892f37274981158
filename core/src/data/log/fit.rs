//! Local polynomial fits of a signal sampled at irregular times: Savitzky–Golay's filter for
//! samples that are not evenly spaced. At a query time t, the least-squares polynomial of
//! order p through the w samples nearest t, read as its value and first derivative at t. On
//! even samples with t at the window's middle this is the Savitzky–Golay filter exactly; with
//! jitter the design matrix follows the samples' own times, so a jittered log is
//! differentiated without first being resampled. The window is centred where the samples
//! allow and one-sided at a trajectory's ends; either way a fit of order ≥ 1 reproduces a
//! straight line, so it does not delay the signal.

use serde::Serialize;

use crate::error::{Error, Result};

/// The fit's window (samples) and polynomial order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Fit {
    pub window: usize,
    pub order: usize,
}

/// Fifteen samples of a cubic: at 1 kHz a 15 ms window, whose velocity noise from positions
/// of σ = 1e-4 rad is about 1e-2 rad/s (docs/logs.md#choosing-the-fit).
pub const DEFAULT_FIT: Fit = Fit {
    window: 15,
    order: 3,
};

/// The highest order taken: beyond it the normal equations of a window of scaled times lose
/// digits and a log's noise is fitted rather than smoothed.
const MAX_ORDER: usize = 6;
/// The widest window taken (a second at 1 kHz): each query's work grows with it.
const MAX_WINDOW: usize = 1001;

/// At one query time: the window's first sample and the weights over its samples that give the
/// fit's value, its rate of change and its second derivative (zero below order 2).
#[derive(Debug, Clone, PartialEq)]
pub struct Stencil {
    pub start: usize,
    pub value: Vec<f64>,
    pub rate: Vec<f64>,
    pub second: Vec<f64>,
}

impl Stencil {
    /// (value, rate) of the signal `y` (sampled at the times the stencil was made on).
    pub fn apply(&self, y: &[f64]) -> (f64, f64) {
        let y = &y[self.start..self.start + self.value.len()];
        let dot = |w: &[f64]| w.iter().zip(y).map(|(w, y)| w * y).sum::<f64>();
        (dot(&self.value), dot(&self.rate))
    }

    /// The second derivative of the fit of `y`.
    pub fn second_of(&self, y: &[f64]) -> f64 {
        let y = &y[self.start..self.start + self.second.len()];
        self.second.iter().zip(y).map(|(w, y)| w * y).sum()
    }
}

impl Fit {
    /// A window of at least order + 2 samples (one more than the polynomial's coefficients,
    /// so that it smooths), at most [`MAX_WINDOW`], of order at most [`MAX_ORDER`].
    pub fn check(&self) -> Result<()> {
        if self.order > MAX_ORDER {
            return Err(Error::invalid(
                "order",
                format!("must be at most {MAX_ORDER}, got {}", self.order),
            ));
        }
        if self.window < self.order + 2 || self.window > MAX_WINDOW {
            return Err(Error::invalid(
                "window",
                format!(
                    "must be between order + 2 = {} and {MAX_WINDOW} samples, got {}",
                    self.order + 2,
                    self.window
                ),
            ));
        }
        Ok(())
    }

    /// The stencil at time `t` over samples at increasing `times` (at least order + 1 of them):
    /// the `window` samples nearest t (fewer when there are fewer), centred on t where the
    /// samples allow.
    pub fn stencil(&self, times: &[f64], t: f64) -> Stencil {
        let w = self.window.min(times.len());
        let p = self.order.min(w - 1);
        let nearest = times.partition_point(|&s| s < t).min(times.len() - 1);
        let start = nearest.saturating_sub(w / 2).min(times.len() - w);
        let window = &times[start..start + w];
        // Times scaled to about [−1, 1]: the normal equations of powers of τ stay well
        // conditioned for the orders taken.
        let half = ((window[w - 1] - window[0]) / 2.0).max(f64::MIN_POSITIVE);
        let tau: Vec<f64> = window.iter().map(|s| (s - t) / half).collect();
        let powers: Vec<Vec<f64>> = tau
            .iter()
            .map(|&x| {
                (0..=p)
                    .scan(1.0, |v, _| Some(std::mem::replace(v, *v * x)))
                    .collect()
            })
            .collect();
        let mut gram = vec![vec![0.0; p + 1]; p + 1];
        for row in &powers {
            for (i, gi) in gram.iter_mut().enumerate() {
                for (j, g) in gi.iter_mut().enumerate() {
                    *g += row[i] * row[j];
                }
            }
        }
        // Coefficient k of the fit is e_kᵀ G⁻¹ Aᵀ y: the weights of c₀ (the value), c₁ (the
        // slope in τ, divided by the scale for the rate) and 2c₂ (over the scale squared).
        let weights = |k: usize, scale: f64| -> Vec<f64> {
            let mut e = vec![0.0; p + 1];
            if k <= p {
                e[k] = 1.0;
            }
            let g = solve(gram.clone(), e);
            powers
                .iter()
                .map(|row| row.iter().zip(&g).map(|(a, g)| a * g).sum::<f64>() / scale)
                .collect()
        };
        Stencil {
            start,
            value: weights(0, 1.0),
            rate: weights(1, half),
            second: weights(2, half * half / 2.0),
        }
    }
}

/// x with G x = b, G symmetric positive definite and small, by Gaussian elimination with
/// partial pivoting.
fn solve(mut g: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for col in 0..n {
        let pivot = (col..n)
            .max_by(|&i, &j| g[i][col].abs().total_cmp(&g[j][col].abs()))
            .expect("a row");
        g.swap(col, pivot);
        b.swap(col, pivot);
        let (top, rest) = g.split_at_mut(col + 1);
        let pivot_row = &top[col];
        for (r, row) in rest.iter_mut().enumerate() {
            let f = row[col] / pivot_row[col];
            for (a, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                *a -= f * p;
            }
            b[col + 1 + r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| g[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / g[row][row];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Jittered times: steps of h ± 5 %.
    fn jittered(count: usize, h: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng::derive(seed, 1);
        let mut t = 0.0;
        (0..count)
            .map(|_| {
                let now = t;
                t += h * (1.0 + 0.05 * (2.0 * rng.uniform() - 1.0));
                now
            })
            .collect()
    }

    /// A cubic is fitted exactly by a cubic, anywhere in the samples, ends included: its value
    /// and its derivative at times between the samples.
    #[test]
    fn a_polynomial_of_the_fits_order_is_exact() {
        let times = jittered(200, 1e-3, 3);
        let f = |t: f64| 0.3 - 2.0 * t + 40.0 * t * t - 900.0 * t * t * t;
        let df = |t: f64| -2.0 + 80.0 * t - 2700.0 * t * t;
        let ddf = |t: f64| 80.0 - 5400.0 * t;
        let y: Vec<f64> = times.iter().map(|&t| f(t)).collect();
        for t in [0.0, 0.0004, 0.05, 0.1234, times[199]] {
            let s = DEFAULT_FIT.stencil(&times, t);
            let ((v, r), a) = (s.apply(&y), s.second_of(&y));
            // Rounding of a 4 × 4 solve on scaled times and sums of 15 terms of order one,
            // divided by the window's half-width (7 ms) once for the rate, twice for the
            // second derivative.
            assert!((v - f(t)).abs() < 1e-12, "value at {t}: {v} vs {}", f(t));
            assert!((r - df(t)).abs() < 1e-8, "rate at {t}: {r} vs {}", df(t));
            assert!(
                (a - ddf(t)).abs() < 1e-5,
                "second at {t}: {a} vs {}",
                ddf(t)
            );
        }
    }

    /// On even samples, at a sample in the window's middle, the weights are Savitzky–Golay's:
    /// for a window of 5 and order 2, (−3, 12, 17, 12, −3)/35 and (−2, −1, 0, 1, 2)/(10 h).
    #[test]
    fn on_even_samples_it_is_savitzky_golay() {
        let h = 0.01;
        let times: Vec<f64> = (0..9).map(|k| k as f64 * h).collect();
        let s = Fit {
            window: 5,
            order: 2,
        }
        .stencil(&times, times[4]);
        assert_eq!(s.start, 2);
        let value = [-3.0, 12.0, 17.0, 12.0, -3.0].map(|v| v / 35.0);
        let rate = [-2.0, -1.0, 0.0, 1.0, 2.0].map(|v| v / (10.0 * h));
        for (a, b) in s.value.iter().zip(value).chain(s.rate.iter().zip(rate)) {
            assert!((a - b).abs() < 1e-12, "{:?} {:?}", s.value, s.rate);
        }
    }

    #[test]
    fn bad_windows_and_orders_are_refused_by_name() {
        let bad = |window, order| Fit { window, order }.check().unwrap_err().to_string();
        assert!(bad(4, 3).starts_with("window"), "{}", bad(4, 3));
        assert!(bad(5000, 3).starts_with("window"));
        assert!(bad(30, 9).starts_with("order"));
        DEFAULT_FIT.check().unwrap();
    }
}

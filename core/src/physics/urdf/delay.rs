//! The efforts' delay behind a log's motion (docs/robots.md#effort-delay): the effort that
//! acts at time t is the one logged at t − δ. A log holds each effort sample from its time
//! to the next (zero-order hold), so over a step [tᵢ, tᵢ₊₁] the mean acting effort is the
//! mean of that held signal over [tᵢ − δ, tᵢ₊₁ − δ]: a weighted sum of the step's own sample
//! and the `lags` before it, the weights each sample's share of the shifted interval. They
//! are piecewise linear in δ, exact for a log's own (uneven) steps, and sum to 1.
//!
//! A row's input block for a robot with a delay is [Δtᵢ, a₁ … a_L, uᵢ, uᵢ₋₁ … uᵢ₋L]: the
//! step's length, each earlier sample's age aₖ = tᵢ − tᵢ₋ₖ, then the samples newest first
//! (m each). Without a delay it is uᵢ alone, as it always was.

use crate::error::Result;

/// The earlier samples a row carries for a delay of at most `bound` seconds in a log of
/// median step `dt`: a quarter more than the bound spans at that step, for uneven steps
/// shorter than the median, and one for the step the shifted interval starts in.
pub fn lags(bound: f64, dt: f64) -> usize {
    (1.25 * bound / dt).ceil() as usize + 1
}

/// The most earlier samples a row may carry: each torque row holds (L + 1)(m + 1) values, so
/// a bound of a second on a 10 kHz log (12 501 lags) would hold ~10⁵ values per transition.
pub const MAX_LAGS: usize = 64;

/// A row's input block's width for `m` inputs and `lags` earlier samples.
pub fn input_width(m: usize, lags: usize) -> usize {
    match lags {
        0 => m,
        l => (l + 1) * (m + 1),
    }
}

/// Each sample's weight (newest first) in the mean effort over the step under delay
/// `delta`, and each weight's derivative in δ (from above: δ ≥ 0 rests on its bound at 0).
/// `times` is [Δtᵢ, a₁ … a_L]; the oldest sample is held back to the log's start.
pub fn weights(times: &[f64], delta: f64) -> (Vec<f64>, Vec<f64>) {
    let dt = times[0];
    let (start, end) = (-delta, dt - delta);
    let mut w = Vec::with_capacity(times.len());
    let mut dw = Vec::with_capacity(times.len());
    for k in 0..times.len() {
        // Sample k is held over [−aₖ, −aₖ₋₁] about tᵢ (a₀ = 0; sample 0 until Δtᵢ).
        let hi = if k == 0 { dt } else { -age(times, k - 1) };
        let lo = if k + 1 == times.len() {
            f64::NEG_INFINITY
        } else {
            -age(times, k)
        };
        let overlap = end.min(hi) - start.max(lo);
        // As δ grows the interval's end leaves `hi` behind once it is below it, its start
        // leaves `lo` once it is above it.
        let slope = -f64::from(u8::from(end <= hi)) + f64::from(u8::from(start > lo));
        let grows = overlap > 0.0 || (overlap == 0.0 && slope > 0.0);
        w.push(overlap.max(0.0) / dt);
        dw.push(if grows { slope / dt } else { 0.0 });
    }
    (w, dw)
}

/// Sample k's age aₖ (a₀ = 0).
fn age(times: &[f64], k: usize) -> f64 {
    if k == 0 { 0.0 } else { times[k] }
}

/// The mean effort over a row's step under delay `delta` and its derivative in δ, from the
/// row's input block (`m` inputs, as laid out above).
pub fn delayed(block: &[f64], m: usize, delta: f64) -> (Vec<f64>, Vec<f64>) {
    let samples = block.len() / (m + 1);
    let (times, u) = block.split_at(samples);
    let (w, dw) = weights(times, delta);
    let (mut mean, mut slope) = (vec![0.0; m], vec![0.0; m]);
    for (k, sample) in u.chunks_exact(m).enumerate() {
        for j in 0..m {
            mean[j] += w[k] * sample[j];
            slope[j] += dw[k] * sample[j];
        }
    }
    (mean, slope)
}

/// The delay in [0, `bound`] whose least-squares residual is least: the torques are linear in
/// every other value at a fixed delay, not in the delay. A grid of half steps finds the
/// basin (the residual is smooth in δ within a step, the weights being linear there), golden
/// sections narrow it to a hundredth of a step.
pub(super) fn best_delay(
    bound: f64,
    dt: f64,
    residual: &dyn Fn(f64) -> Result<f64>,
) -> Result<f64> {
    let h = (0.5 * dt).min(bound);
    let count = (bound / h).ceil() as usize;
    let grid: Vec<f64> = (0..=count).map(|k| (k as f64 * h).min(bound)).collect();
    let mut best = (f64::INFINITY, 0.0);
    for &d in &grid {
        let r = residual(d)?;
        if r < best.0 {
            best = (r, d);
        }
    }
    let (mut lo, mut hi) = ((best.1 - h).max(0.0), (best.1 + h).min(bound));
    const PHI: f64 = 0.618_033_988_749_894_9;
    let (mut a, mut b) = (hi - PHI * (hi - lo), lo + PHI * (hi - lo));
    let (mut ra, mut rb) = (residual(a)?, residual(b)?);
    while hi - lo > 0.01 * dt {
        if ra < rb {
            (hi, b, rb) = (b, a, ra);
            a = hi - PHI * (hi - lo);
            ra = residual(a)?;
        } else {
            (lo, a, ra) = (a, b, rb);
            b = lo + PHI * (hi - lo);
            rb = residual(b)?;
        }
    }
    let found = if ra < rb { (ra, a) } else { (rb, b) };
    Ok(if found.0 < best.0 { found.1 } else { best.1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weights against the held signal's mean over the shifted step taken by brute force
    /// (a million-point midpoint sum, exact to 1e-6 of a step), and their δ-slopes against
    /// central differences (exact within a piece: the weights are linear there), on uneven
    /// steps and at delays inside pieces, on a knot, and beyond the history.
    #[test]
    fn weights_are_the_shifted_held_signal_s_shares() {
        // Sample times 0, −0.8, −2.1, −3.0 ms (newest first); the step 1.2 ms.
        let times = [1.2e-3, 0.8e-3, 2.1e-3, 3.0e-3];
        let starts = [0.0, -0.8e-3, -2.1e-3, -3.0e-3];
        let held = |t: f64| (0..4).find(|&k| t >= starts[k]).unwrap_or(3);
        for delta in [0.0, 0.3e-3, 0.8e-3, 1.7e-3, 2.5e-3, 4.4e-3] {
            let (w, dw) = weights(&times, delta);
            let count = 1_000_000;
            let mut share = [0.0; 4];
            for i in 0..count {
                let t = -delta + (i as f64 + 0.5) / count as f64 * times[0];
                share[held(t)] += 1.0 / count as f64;
            }
            for k in 0..4 {
                assert!(
                    (w[k] - share[k]).abs() < 1e-5,
                    "δ {delta}: {w:?} vs {share:?}"
                );
            }
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let h = 1e-8;
            let (up, _) = weights(&times, delta + h);
            for k in 0..4 {
                let fd = (up[k] - w[k]) / h;
                assert!(
                    (dw[k] - fd).abs() < 1e-3 * (1.0 / times[0]),
                    "δ {delta}: {dw:?}"
                );
            }
        }
    }

    /// The mean effort is the weights' sum of the samples, and no delay gives the step's own.
    #[test]
    fn a_row_s_mean_effort() {
        let block = [1e-3, 1e-3, 2e-3, 5.0, -1.0, 3.0, 0.5, 1.0, 2.0];
        let (u, du) = delayed(&block, 2, 0.0);
        assert_eq!(u, vec![5.0, -1.0]);
        assert_eq!(du, vec![(3.0 - 5.0) / 1e-3, (0.5 + 1.0) / 1e-3]);
        let (u, _) = delayed(&block, 2, 1.5e-3);
        assert!(
            (u[0] - 0.5 * (3.0 + 1.0)).abs() < 1e-12 && (u[1] - 0.5 * (0.5 + 2.0)).abs() < 1e-12
        );
    }
}

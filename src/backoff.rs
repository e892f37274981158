//! Exponential backoff with jitter: how long to wait before trying a shared service (the
//! database, the object store) again. Waits double from `first` up to `cap`, and each is drawn
//! from its upper half, so that processes that failed together do not retry together.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use crate::rng::Rng;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    pub first: Duration,
    pub cap: Duration,
}

impl Backoff {
    pub const fn new(first: Duration, cap: Duration) -> Self {
        Self { first, cap }
    }

    /// The wait before try `retry + 1` (`retry` counts from 0): uniform in [d/2, d] with
    /// d = min(first · 2^retry, cap).
    pub fn delay(&self, retry: u32) -> Duration {
        let full = self
            .first
            .saturating_mul(1u32 << retry.min(20))
            .min(self.cap);
        full.mul_f64(0.5 + 0.5 * jitter())
    }
}

/// Uniform in [0, 1), from a process-wide stream seeded by the clock and the process id, so
/// that two processes started in the same instant still draw different waits.
fn jitter() -> f64 {
    static STATE: AtomicU64 = AtomicU64::new(0);
    let mut seed = STATE.fetch_add(1, Ordering::Relaxed);
    if seed == 0 {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64);
        seed = nanos ^ (u64::from(std::process::id()) << 32);
        STATE.store(seed | 1, Ordering::Relaxed);
    }
    Rng::derive(seed, 0x6a69_7474_6572).uniform()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waits_double_up_to_the_cap_within_their_upper_half() {
        let b = Backoff::new(Duration::from_millis(100), Duration::from_secs(2));
        for (retry, full_ms) in [
            (0, 100),
            (1, 200),
            (3, 800),
            (4, 1600),
            (5, 2000),
            (40, 2000),
        ] {
            for _ in 0..50 {
                let d = b.delay(retry).as_secs_f64() * 1e3;
                let full = f64::from(full_ms);
                assert!((full / 2.0..=full).contains(&d), "retry {retry}: {d} ms");
            }
        }
        // Jittered: fifty draws are not all one value.
        let draws: std::collections::BTreeSet<u128> =
            (0..50).map(|_| b.delay(2).as_nanos()).collect();
        assert!(draws.len() > 40, "{draws:?}");
    }
}

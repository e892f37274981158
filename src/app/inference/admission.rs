//! Admission of heavy inference work: a bounded number computes at once on the blocking
//! pool, a bounded number waits. Short calls (a controller's batch), long calls (plans,
//! evaluations, large batches) and rollout streams each have a pool of their own, so that
//! seconds of planning never queue a controller's Predict behind them.
//!
//! A class of calls computes on threads of its own, made once with it (a rayon pool of as
//! many threads as it has permits): a lone large batch splits over the idle ones
//! (`infer::calls`), and no call ever starts a thread.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use tokio::sync::Semaphore;

use crate::error::{Error, Result};

/// Heavy calls waiting per permit before further ones are refused: a queue, not a pile.
const WAITING_PER_PERMIT: usize = 16;

/// The most one-step evaluations (states × members × passes, see [`Class::of`]) a short
/// call may take: about 4096 × 15–20 µs ≈ 60–80 ms on the double pendulum, so a short call
/// waits at most that long behind another. A 16-state Predict is 16, a 100-step Tvlqr of the
/// double pendulum 700.
pub const SHORT_EVALUATIONS: usize = 4096;

/// Where a call computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    /// On the executor thread itself: less work than a hop to the blocking pool costs.
    Inline,
    /// In the short class (`--max-short-calls`): a controller's call of milliseconds.
    Short,
    /// In the long class (`--max-heavy-calls`): plans, evaluations and large batches.
    Long,
}

impl Class {
    /// The class of a call of `evaluations` one-step evaluations (a linearization counts
    /// its 2nv + m + 1 directions); `inline` when the call is small enough for the executor.
    pub fn of(inline: bool, evaluations: usize) -> Self {
        if inline {
            Class::Inline
        } else if evaluations <= SHORT_EVALUATIONS {
            Class::Short
        } else {
            Class::Long
        }
    }
}

/// Admission of heavy inference work: `permits` compute at once, a bounded number wait.
/// Calls and rollout streams each have their own (see [`Heavy::streaming`]).
pub struct Heavy {
    permits: Arc<Semaphore>,
    waiting: AtomicUsize,
    max_waiting: usize,
    /// Calls computing now.
    busy: Arc<AtomicUsize>,
    /// The setting that sizes this pool, named when a call is turned away.
    flag: &'static str,
    /// The threads its calls compute on; `None`: each on its blocking thread alone.
    threads: Option<Arc<rayon::ThreadPool>>,
}

/// Decrements the computing count when the computation ends, however it ends.
struct Busy(Arc<AtomicUsize>);

impl Drop for Busy {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

/// Decrements the waiting count however the wait ends (a caller's deadline drops the future).
struct Waiting<'a>(&'a AtomicUsize);

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Heavy {
    /// A pool for calls: `permits` at once (set by `flag`), a bounded queue behind them,
    /// computing on as many threads named `graybox-{name}-k`. Without threads (one permit,
    /// or none to be had) each call computes on its blocking thread alone.
    pub fn new(permits: usize, flag: &'static str, name: &'static str) -> Self {
        let threads = (permits > 1)
            .then(|| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(permits)
                    .thread_name(move |k| format!("graybox-{name}-{k}"))
                    .build()
            })
            .and_then(|built| {
                built
                    .inspect_err(|e| tracing::warn!(error = %e, name, "no threads for its calls"))
                    .ok()
                    .map(Arc::new)
            });
        Self::with_threads(permits, flag, threads)
    }

    fn with_threads(
        permits: usize,
        flag: &'static str,
        threads: Option<Arc<rayon::ThreadPool>>,
    ) -> Self {
        let permits = permits.max(1);
        Self {
            permits: Arc::new(Semaphore::new(permits)),
            waiting: AtomicUsize::new(0),
            max_waiting: permits * WAITING_PER_PERMIT,
            busy: Arc::default(),
            flag,
            threads,
        }
    }

    /// Calls computing now (for tests and telemetry).
    pub fn busy(&self) -> usize {
        self.busy.load(Ordering::SeqCst)
    }

    /// A pool for rollout streams: their chunks queue without a cap (a waiting stream is a
    /// parked task holding no thread, and streams are capped per connection), apart from
    /// calls, so that many streams cannot crowd Predict, Linearize or Tvlqr out.
    /// A rollout's steps run one after another, so a stream needs no threads of its own.
    pub fn streaming(permits: usize, flag: &'static str) -> Self {
        Self {
            max_waiting: usize::MAX,
            ..Self::with_threads(permits, flag, None)
        }
    }

    /// Runs `f` once a permit is free, on this pool's threads (its blocking thread waits),
    /// or on the blocking pool; the permit is held until `f` returns, even if the caller has
    /// gone.
    pub async fn run<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T> {
        if self.waiting.fetch_add(1, Ordering::SeqCst) >= self.max_waiting {
            self.waiting.fetch_sub(1, Ordering::SeqCst);
            return Err(Error::Busy(format!(
                "{} inference calls like this one are already waiting; retry later ({})",
                self.max_waiting, self.flag
            )));
        }
        let guard = Waiting(&self.waiting);
        let permit = self
            .permits
            .clone()
            .acquire_owned()
            .await
            .map_err(|_| Error::Internal("the inference pool is closed".into()))?;
        drop(guard);
        self.busy.fetch_add(1, Ordering::SeqCst);
        let busy = self.busy.clone();
        let threads = self.threads.clone();
        tokio::task::spawn_blocking(move || {
            let _permit = permit;
            let _busy = Busy(busy);
            match threads {
                Some(pool) => pool.install(f),
                None => f(),
            }
        })
        .await
        .map_err(|e| Error::Internal(format!("inference task failed: {e}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Past its bounded queue a heavy call is told to come back (Busy: 503 with Retry-After,
    /// UNAVAILABLE), not that it is too large (it was a 413).
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn past_the_queue_a_call_is_busy_not_too_large() {
        let heavy = Arc::new(Heavy::new(1, "--max-heavy-calls", "long"));
        let (release, held) = std::sync::mpsc::channel::<()>();
        let held = Arc::new(std::sync::Mutex::new(held));
        let running = {
            let (heavy, held) = (heavy.clone(), held.clone());
            tokio::spawn(async move { heavy.run(move || held.lock().unwrap().recv()).await })
        };
        while heavy.permits.available_permits() > 0 {
            tokio::task::yield_now().await;
        }
        let waiting: Vec<_> = (0..WAITING_PER_PERMIT)
            .map(|_| {
                let heavy = heavy.clone();
                tokio::spawn(async move { heavy.run(|| ()).await })
            })
            .collect();
        while heavy.waiting.load(Ordering::SeqCst) < WAITING_PER_PERMIT {
            tokio::task::yield_now().await;
        }
        match heavy.run(|| ()).await {
            Err(Error::Busy(m)) => {
                assert!(
                    m.contains("already waiting") && m.contains("--max-heavy-calls"),
                    "{m}"
                )
            }
            other => panic!("{other:?}"),
        }
        release.send(()).unwrap();
        running.await.unwrap().unwrap().unwrap();
        for w in waiting {
            w.await.unwrap().unwrap();
        }
    }

    /// A class of several permits computes on its own named threads, where a batch may split
    /// (`rayon::current_thread_index`); one permit, or a stream, on the blocking thread.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn calls_compute_on_the_class_threads() {
        let whose = || {
            let name = std::thread::current().name().map(str::to_owned);
            (rayon::current_thread_index(), name)
        };
        let (index, name) = Heavy::new(2, "--max-short-calls", "short")
            .run(whose)
            .await
            .unwrap();
        assert!(index.is_some(), "not on the class's threads");
        assert!(name.is_some_and(|n| n.starts_with("graybox-short-")));
        for alone in [
            Heavy::new(1, "--max-heavy-calls", "long"),
            Heavy::streaming(2, "--max-heavy-calls"),
        ] {
            assert_eq!(alone.run(whose).await.unwrap().0, None);
        }
    }
}

//! Admission of heavy inference work: a bounded number computes at once on the blocking
//! pool, a bounded number waits; calls and rollout streams each have a pool.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use tokio::sync::Semaphore;

use crate::error::{Error, Result};

/// Heavy calls waiting per permit before further ones are refused: a queue, not a pile.
const WAITING_PER_PERMIT: usize = 16;

/// Admission of heavy inference work: `permits` compute at once, a bounded number wait.
/// Calls and rollout streams each have their own (see [`Heavy::streaming`]).
pub struct Heavy {
    permits: Arc<Semaphore>,
    waiting: AtomicUsize,
    max_waiting: usize,
}

/// Decrements the waiting count however the wait ends (a caller's deadline drops the future).
struct Waiting<'a>(&'a AtomicUsize);

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Heavy {
    /// A pool for calls: `permits` at once, a bounded queue behind them.
    pub fn new(permits: usize) -> Self {
        let permits = permits.max(1);
        Self {
            permits: Arc::new(Semaphore::new(permits)),
            waiting: AtomicUsize::new(0),
            max_waiting: permits * WAITING_PER_PERMIT,
        }
    }

    /// A pool for rollout streams: their chunks queue without a cap (a waiting stream is a
    /// parked task holding no thread, and streams are capped per connection), apart from
    /// calls, so that many streams cannot crowd Predict, Linearize or Tvlqr out.
    pub fn streaming(permits: usize) -> Self {
        Self {
            max_waiting: usize::MAX,
            ..Self::new(permits)
        }
    }

    /// Runs `f` on the blocking pool once a permit is free; the permit is held until `f`
    /// returns, even if the caller has gone.
    pub async fn run<T: Send + 'static>(
        &self,
        f: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T> {
        if self.waiting.fetch_add(1, Ordering::SeqCst) >= self.max_waiting {
            self.waiting.fetch_sub(1, Ordering::SeqCst);
            return Err(Error::Busy(format!(
                "{} heavy inference calls are already waiting; retry later (--max-heavy-calls)",
                self.max_waiting
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
        tokio::task::spawn_blocking(move || {
            let _permit = permit;
            f()
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
        let heavy = Arc::new(Heavy::new(1));
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
            Err(Error::Busy(m)) => assert!(m.contains("already waiting"), "{m}"),
            other => panic!("{other:?}"),
        }
        release.send(()).unwrap();
        running.await.unwrap().unwrap().unwrap();
        for w in waiting {
            w.await.unwrap().unwrap();
        }
    }
}

//! What a call may take in this process: the memory it is admitted under (the service's own
//! estimate, `infer::limits`, against a budget the module keeps), and Ctrl-C, heard while the
//! core computes with the GIL released.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;

use crate::convert::{py_error, py_error_at, whole};
use graybox_core::error::Error;
use graybox_core::infer::limits::{Cost, DEFAULT_MAX_CALL_MEMORY_MB};

/// The per-call memory budget, MiB: the service's default, so that what it refuses (a plan
/// that would take gigabytes) is refused here before it aborts the process on allocation.
static BUDGET_MB: AtomicUsize = AtomicUsize::new(DEFAULT_MAX_CALL_MEMORY_MB);

/// The most memory one call may take, in MiB (≥ 1): a call whose estimate is over it raises
/// GrayboxError RESOURCE_EXHAUSTED naming the argument at fault, before computing.
#[pyfunction]
pub fn set_memory_budget_mb(py: Python<'_>, mb: i128) -> PyResult<()> {
    let mb = whole("mb", mb, (usize::MAX >> 20) as u64).map_err(|e| py_error(py, e))?;
    if mb == 0 {
        return Err(py_error(py, Error::invalid("mb", "must be at least 1")));
    }
    BUDGET_MB.store(mb as usize, Ordering::Relaxed);
    Ok(())
}

/// The per-call memory budget in MiB (`set_memory_budget_mb`).
#[pyfunction]
pub fn memory_budget_mb() -> usize {
    BUDGET_MB.load(Ordering::Relaxed)
}

/// The call, unless its estimate is over the budget: RESOURCE_EXHAUSTED naming its field.
pub fn admit(py: Python<'_>, cost: &Cost) -> PyResult<()> {
    let budget = memory_budget_mb() << 20;
    (cost.within(budget, "graybox_native.set_memory_budget_mb"))
        .map_err(|e| py_error_at(py, e, cost.field))
}

/// How often a long call asks the interpreter for a pending signal: well within the 100 ms a
/// Ctrl-C should take, and rare enough that taking the GIL costs nothing measurable. A call
/// shorter than this never asks.
const SIGNAL_CHECK: Duration = Duration::from_millis(50);

/// The core's stop check for one call: it hears a signal (Ctrl-C) and keeps the exception
/// its handler raised (KeyboardInterrupt), which the call raises instead of its answer. The
/// core polls it from any of its threads; only the main thread's check runs the handlers.
pub struct Interrupt {
    start: Instant,
    /// Nanoseconds after `start` of the next check.
    next: AtomicU64,
    heard: AtomicBool,
    raised: Mutex<Option<PyErr>>,
}

impl Interrupt {
    pub fn new() -> Self {
        Self {
            start: Instant::now(),
            next: AtomicU64::new(SIGNAL_CHECK.as_nanos() as u64),
            heard: AtomicBool::new(false),
            raised: Mutex::new(None),
        }
    }

    /// Whether the call must stop: a signal's handler raised.
    pub fn stop(&self) -> bool {
        if self.heard.load(Ordering::Relaxed) {
            return true;
        }
        let now = self.start.elapsed().as_nanos() as u64;
        let next = self.next.load(Ordering::Relaxed);
        let later = now + SIGNAL_CHECK.as_nanos() as u64;
        // One thread checks per period; the others go on computing.
        if now < next
            || (self.next)
                .compare_exchange(next, later, Ordering::Relaxed, Ordering::Relaxed)
                .is_err()
        {
            return false;
        }
        let Err(e) = Python::attach(|py| py.check_signals()) else {
            return false;
        };
        *self.raised.lock().unwrap_or_else(PoisonError::into_inner) = Some(e);
        self.heard.store(true, Ordering::Relaxed);
        true
    }

    /// The call's answer (`None` or `Error::Cancelled`: it stopped), or the exception a
    /// signal's handler raised meanwhile.
    pub fn answer<T>(&self, py: Python<'_>, out: Result<Option<T>, Error>) -> PyResult<T> {
        let raised = self
            .raised
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .take();
        if let Some(e) = raised {
            return Err(e);
        }
        match out {
            Ok(Some(v)) => Ok(v),
            Ok(None) | Err(Error::Cancelled) => Err(PyKeyboardInterrupt::new_err("interrupted")),
            Err(e) => Err(py_error(py, e)),
        }
    }
}

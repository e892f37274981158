//! Independent work items on all cores, with progress on stderr: on a terminal a bar for the
//! whole experiment and a status line per worker (what it trains, which epoch); otherwise one
//! line per finished cell and each worker's status once a minute.

use std::cell::Cell;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

/// The experiment's progress in cells.
pub struct Progress {
    multi: Option<MultiProgress>,
    bar: Option<ProgressBar>,
    done: AtomicUsize,
    total: usize,
    start: Instant,
}

/// How often a worker's status goes to a log that is not a terminal.
const LOG_EVERY: Duration = Duration::from_secs(60);

/// One worker's status line (each worker owns its own).
pub struct Status {
    line: Option<ProgressBar>,
    logged: Cell<Instant>,
}

impl Status {
    /// Shows what the worker is doing now: on a terminal in its line, in a log once a minute.
    pub fn show(&self, what: &str) {
        match &self.line {
            Some(l) => l.set_message(what.to_string()),
            None if self.logged.get().elapsed() >= LOG_EVERY => {
                eprintln!("  {what}");
                self.logged.set(Instant::now());
            }
            None => {}
        }
    }
}

impl Progress {
    /// `total` cells, `done` of them finished by earlier invocations.
    pub fn new(total: usize, done: usize) -> Self {
        let (multi, bar) = if std::io::stderr().is_terminal() {
            let multi = MultiProgress::new();
            let bar = multi.add(ProgressBar::new(total as u64));
            bar.set_style(
                ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:30}] {pos}/{len} cells, eta {eta} {msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            bar.set_position(done as u64);
            (Some(multi), Some(bar))
        } else {
            (None, None)
        };
        Self {
            multi,
            bar,
            done: AtomicUsize::new(done),
            total,
            start: Instant::now(),
        }
    }

    fn status(&self) -> Status {
        let line = self.multi.as_ref().map(|m| {
            let l = m.add(ProgressBar::new_spinner());
            l.set_style(ProgressStyle::with_template("  {msg}").expect("valid template"));
            l
        });
        Status {
            line,
            logged: Cell::new(Instant::now()),
        }
    }

    /// `count` more cells are finished (or no longer needed); `what` says which.
    pub fn cells_done(&self, count: usize, what: &str) {
        let done = self.done.fetch_add(count, Ordering::SeqCst) + count;
        match &self.bar {
            Some(b) => {
                b.set_position(done as u64);
                b.println(what);
            }
            None => eprintln!(
                "[{done}/{}] {what} ({:.0} s)",
                self.total,
                self.start.elapsed().as_secs_f64()
            ),
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// The flags every experiment takes besides its own settings.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct RunArgs {
    /// A small run for tests (well under a minute).
    #[arg(long)]
    pub quick: bool,
    /// Trainings (model-based RL: runs) at once [default: every core].
    #[arg(long, default_value_t = 0, hide_default_value = true)]
    pub jobs: usize,
}

/// `work` on every item, `jobs` at a time, each worker taking the next item when it is free;
/// results in the order of `items`.
pub fn parallel<T: Sync, R: Send>(
    items: &[T],
    jobs: usize,
    progress: &Progress,
    work: impl Fn(&T, &Status) -> R + Sync,
) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..items.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..jobs.clamp(1, items.len().max(1)) {
            s.spawn(|| {
                let status = progress.status();
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(item) = items.get(i) else { break };
                    let r = work(item, &status);
                    results.lock().expect("results lock")[i] = Some(r);
                }
                if let Some(l) = status.line {
                    l.finish_and_clear();
                }
            });
        }
    });
    results
        .into_inner()
        .expect("results lock")
        .into_iter()
        .map(|r| r.expect("every item ran"))
        .collect()
}

/// The worker threads to use: `jobs`, or every core when 0.
pub fn threads(jobs: usize) -> usize {
    if jobs > 0 {
        return jobs;
    }
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

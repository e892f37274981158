//! In-process counters for `/metrics` (Prometheus text exposition format 0.0.4).

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use crate::records::JobState;

/// Upper bounds (seconds) of the request-latency histogram.
const BUCKETS: [f64; 12] = [
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0,
];

#[derive(Default)]
struct Histogram {
    counts: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
}

/// Jobs by state.
type JobCounts = Vec<(JobState, i64)>;

#[derive(Default)]
pub struct Telemetry {
    requests: Mutex<BTreeMap<(String, String, u16), u64>>,
    latency: Mutex<BTreeMap<(String, String), Histogram>>,
    pub epochs_trained: AtomicU64,
    /// Long computations stopped because the caller's deadline passed or it went away.
    pub computations_stopped: AtomicU64,
    /// Store reads made to follow jobs' progress (server-sent events), all subscribers together.
    pub job_polls: AtomicU64,
    /// The jobs by state as last read from the database, and when.
    job_counts: Mutex<Option<(Instant, JobCounts)>>,
    /// Held while the job counts are read: one read at a time, however many scrapes.
    pub counting: tokio::sync::Mutex<()>,
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

impl Telemetry {
    pub fn record_request(&self, method: &str, route: &str, status: u16, seconds: f64) {
        let mut r = self.requests.lock().expect("telemetry lock");
        *r.entry((method.to_string(), route.to_string(), status))
            .or_default() += 1;
        drop(r);
        let mut l = self.latency.lock().expect("telemetry lock");
        let h = l
            .entry((method.to_string(), route.to_string()))
            .or_default();
        for (i, b) in BUCKETS.iter().enumerate() {
            if seconds <= *b {
                h.counts[i] += 1;
            }
        }
        h.count += 1;
        h.sum += seconds;
    }

    pub fn set_job_counts(&self, jobs: JobCounts) {
        *self.job_counts.lock().expect("telemetry lock") = Some((Instant::now(), jobs));
    }

    /// The exposition text, with the job counts last read from the store and their age
    /// (NaN before the first read).
    pub fn render(&self) -> String {
        let mut out = String::new();
        let counts = self.job_counts.lock().expect("telemetry lock").clone();
        out.push_str("# HELP graybox_jobs Jobs by state.\n# TYPE graybox_jobs gauge\n");
        for (state, count) in counts.iter().flat_map(|(_, jobs)| jobs) {
            let _ = writeln!(out, "graybox_jobs{{state=\"{}\"}} {count}", state.as_str());
        }
        let age = counts.map_or(f64::NAN, |(read, _)| read.elapsed().as_secs_f64());
        out.push_str("# HELP graybox_jobs_age_seconds How old the graybox_jobs counts are.\n");
        out.push_str("# TYPE graybox_jobs_age_seconds gauge\n");
        let _ = writeln!(out, "graybox_jobs_age_seconds {age}");
        self.render_counters(&mut out);
        self.render_requests(&mut out);
        self.render_latency(&mut out);
        out
    }

    fn render_counters(&self, out: &mut String) {
        let counters = [
            (
                "graybox_epochs_trained_total",
                "Training epochs completed by this process.",
                &self.epochs_trained,
            ),
            (
                "graybox_computations_stopped_total",
                "Computations stopped by a deadline or cancellation.",
                &self.computations_stopped,
            ),
            (
                "graybox_job_polls_total",
                "Store reads made to follow jobs (all event subscribers together).",
                &self.job_polls,
            ),
        ];
        for (name, help, value) in counters {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} counter");
            let _ = writeln!(out, "{name} {}", value.load(Ordering::Relaxed));
        }
    }

    fn render_requests(&self, out: &mut String) {
        out.push_str(
            "# HELP graybox_http_requests_total HTTP requests by method, route and status.\n",
        );
        out.push_str("# TYPE graybox_http_requests_total counter\n");
        for ((method, route, status), n) in self.requests.lock().expect("telemetry lock").iter() {
            let _ = writeln!(
                out,
                "graybox_http_requests_total{{method=\"{}\",route=\"{}\",status=\"{status}\"}} {n}",
                escape(method),
                escape(route)
            );
        }
    }

    fn render_latency(&self, out: &mut String) {
        const NAME: &str = "graybox_http_request_duration_seconds";
        let _ = writeln!(out, "# HELP {NAME} HTTP request latency.");
        let _ = writeln!(out, "# TYPE {NAME} histogram");
        for ((method, route), h) in self.latency.lock().expect("telemetry lock").iter() {
            let labels = format!("method=\"{}\",route=\"{}\"", escape(method), escape(route));
            for (b, c) in BUCKETS.iter().zip(h.counts) {
                let _ = writeln!(out, "{NAME}_bucket{{{labels},le=\"{b}\"}} {c}");
            }
            let _ = writeln!(out, "{NAME}_bucket{{{labels},le=\"+Inf\"}} {}", h.count);
            let _ = writeln!(out, "{NAME}_sum{{{labels}}} {}", h.sum);
            let _ = writeln!(out, "{NAME}_count{{{labels}}} {}", h.count);
        }
    }
}

//! The service's one settings type: `graybox serve`'s flags (and `GRAYBOX_*` environment),
//! what the core, the adapters and the workers read. The limits bound what one accepted
//! request may cost; README documents each flag.

use std::path::PathBuf;

use clap::Args;

use crate::control::plan::DEFAULT_MAX_PLAN_HORIZON;
use crate::error::{Error, Result};
use crate::infer::limits::DEFAULT_MAX_CALL_MEMORY_MB;

/// Blocking threads of the service's runtime: training jobs, heavy inference calls and
/// rollout chunks (at most `--max-heavy-calls` each) and model loads. A cap, so that no burst
/// of requests can make the process spawn hundreds of threads.
pub const MAX_BLOCKING_THREADS: usize = 32;

#[derive(Args, Debug, Clone)]
pub struct Settings {
    /// REST listen address.
    #[arg(long, env = "GRAYBOX_HTTP", default_value = "127.0.0.1:8080")]
    pub http: String,
    /// gRPC listen address.
    #[arg(long, env = "GRAYBOX_GRPC", default_value = "127.0.0.1:50051")]
    pub grpc: String,
    /// The database and the training workers (`graybox worker` takes exactly these).
    #[command(flatten)]
    pub worker: WorkerSettings,
    /// Largest dataset upload (JSON or CSV), in MiB.
    #[arg(long, env = "GRAYBOX_MAX_BODY_MB", default_value_t = 128)]
    pub max_body_mb: usize,
    /// Largest model file upload (POST /v1/models), in MiB.
    #[arg(long, env = "GRAYBOX_MAX_MODEL_MB", default_value_t = 64)]
    pub max_model_mb: usize,
    /// Largest template document, or job request embedding one, in MiB.
    #[arg(long, env = "GRAYBOX_MAX_TEMPLATE_MB", default_value_t = 8)]
    pub max_template_mb: usize,
    /// Memory all request bodies in flight may take while read and parsed, in MiB (each
    /// reserves its size times its kind's measured cost; past it: 503 with Retry-After).
    #[arg(long, env = "GRAYBOX_MAX_INFLIGHT_BODY_MB", default_value_t = 1536)]
    pub max_inflight_body_mb: usize,
    /// Longest gRPC Rollout (and Tvlqr horizon), in steps.
    #[arg(long, env = "GRAYBOX_MAX_ROLLOUT_STEPS", default_value_t = 100_000)]
    pub max_rollout_steps: usize,
    /// Longest gRPC Plan horizon, in steps.
    #[arg(long, env = "GRAYBOX_MAX_PLAN_HORIZON", default_value_t = DEFAULT_MAX_PLAN_HORIZON)]
    pub max_plan_horizon: usize,
    /// Largest gRPC message, in MiB.
    #[arg(long, env = "GRAYBOX_GRPC_MAX_MESSAGE_MB", default_value_t = 64)]
    pub grpc_max_message_mb: usize,
    /// Concurrent gRPC calls (HTTP/2 streams) per connection.
    #[arg(long, env = "GRAYBOX_GRPC_MAX_STREAMS", default_value_t = 100)]
    pub grpc_max_streams: u32,
    /// Memory one inference call may take, in MiB (larger calls: RESOURCE_EXHAUSTED).
    #[arg(long, env = "GRAYBOX_MAX_CALL_MEMORY_MB", default_value_t = DEFAULT_MAX_CALL_MEMORY_MB)]
    pub max_call_memory_mb: usize,
    /// Long inference calls computing at once (plans, evaluations, energy reports and
    /// batches over the short size; the others wait); rollout chunks get as many.
    #[arg(long, env = "GRAYBOX_MAX_HEAVY_CALLS", default_value_t = 2)]
    pub max_heavy_calls: usize,
    /// Short inference calls computing at once (a controller's Predict, Linearize, Tvlqr or
    /// Energy of up to 4096 one-step evaluations), apart from the long ones so that they
    /// never queue behind a plan.
    #[arg(long, env = "GRAYBOX_MAX_SHORT_CALLS", default_value_t = 2)]
    pub max_short_calls: usize,
    /// Estimated peak memory of one training job, in MiB (larger jobs: 422 at submission).
    #[arg(long, env = "GRAYBOX_MAX_JOB_MEMORY_MB", default_value_t = 4096)]
    pub max_job_memory_mb: usize,
    /// Trainable parameters of one model.
    #[arg(long, env = "GRAYBOX_MAX_MODEL_PARAMS", default_value_t = 1_000_000)]
    pub max_model_params: usize,
    /// Generalized coordinates n a job may train on.
    #[arg(long, env = "GRAYBOX_MAX_DOF", default_value_t = 64)]
    pub max_dof: usize,
    /// With a token, REST writes and every gRPC Dynamics call need `Authorization: Bearer <token>`.
    #[arg(long, env = "GRAYBOX_API_TOKEN", hide_env_values = true)]
    pub api_token: Option<String>,
    /// Require the token for REST reads too.
    #[arg(long, env = "GRAYBOX_AUTH_READS")]
    pub auth_reads: bool,
    /// Serve REST and gRPC over TLS with this certificate chain (PEM); needs --tls-key.
    #[arg(long, env = "GRAYBOX_TLS_CERT", requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// The private key (PEM) of --tls-cert.
    #[arg(long, env = "GRAYBOX_TLS_KEY", requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
}

/// What a training worker reads: the database, how many jobs train at once and how, the
/// lease and the shutdown grace. `graybox serve` flattens it into [`Settings`]; `graybox
/// worker` takes it alone, so one flag means one thing in both.
#[derive(Args, Debug, Clone)]
pub struct WorkerSettings {
    /// SQLite database file (created if missing), or a PostgreSQL URL
    /// (postgres://user:password@host:port/database?sslmode=require) that several graybox
    /// processes share.
    #[arg(long, env = "GRAYBOX_DB", default_value = "./graybox.db")]
    pub db: String,
    /// Where datasets, checkpoints and model files go: an object store, `file:///dir` or
    /// `s3://bucket/prefix` (S3 and S3-compatible stores, configured by the AWS_* environment
    /// variables) [default: inline, in the database's rows].
    #[arg(long, env = "GRAYBOX_BLOBS")]
    pub blobs: Option<String>,
    /// Training workers (jobs trained at once).
    #[arg(long, env = "GRAYBOX_WORKERS", default_value_t = 1)]
    pub workers: usize,
    /// Threads each training job computes on [default: cores / workers, at least 1]. A job
    /// keeps the split of its batches when it resumes, so its results do not depend on it.
    #[arg(long, env = "GRAYBOX_JOB_THREADS")]
    pub job_threads: Option<usize>,
    /// Checkpoint a running job every this many epochs.
    #[arg(long, env = "GRAYBOX_CHECKPOINT_EVERY", default_value_t = 10)]
    pub checkpoint_every: usize,
    /// A job whose worker has not heartbeated for this long is reclaimed.
    #[arg(long, env = "GRAYBOX_LEASE_SECS", default_value_t = 30)]
    pub lease_secs: u64,
    /// Seconds from SIGTERM (or ctrl-c) until the process exits even if running jobs have not
    /// reached an epoch end (they go back to the queue from their last checkpoint) or calls
    /// are still computing. The default leaves room under a 30 s kill.
    #[arg(long, env = "GRAYBOX_SHUTDOWN_GRACE_SECS", default_value_t = 20)]
    pub shutdown_grace_secs: u64,
    /// Times a job's worker may die (lease expired) before the job fails.
    #[arg(long, env = "GRAYBOX_MAX_ATTEMPTS", default_value_t = 3)]
    pub max_attempts: u32,
    /// One call to the object store that has not answered by then is abandoned and tried
    /// again.
    #[arg(long, env = "GRAYBOX_BLOBS_TIMEOUT_SECS", default_value_t = 30)]
    pub blobs_timeout_secs: u64,
    /// How long a failing object-store call is tried again (with backoff) before its request
    /// or job sees the error.
    #[arg(long, env = "GRAYBOX_BLOBS_RETRY_SECS", default_value_t = 30)]
    pub blobs_retry_secs: u64,
    /// How long a job's storage may keep failing before the job fails; until then it goes
    /// back to the queue after each failure, waiting longer each time (outages are the
    /// cluster's, not the job's).
    #[arg(long, env = "GRAYBOX_STORAGE_PATIENCE_SECS", default_value_t = 1800)]
    pub storage_patience_secs: u64,
}

impl Default for Settings {
    /// The flags' defaults (without reading the environment).
    fn default() -> Self {
        declared_defaults()
    }
}

impl Default for WorkerSettings {
    /// The flags' defaults (without reading the environment).
    fn default() -> Self {
        declared_defaults()
    }
}

/// Parsing an empty command line gives exactly the declared defaults; the environment is
/// ignored so that a library user's GRAYBOX_* variables cannot change them.
fn declared_defaults<T: Args>() -> T {
    #[derive(clap::Parser)]
    struct Defaults<T: Args> {
        #[command(flatten)]
        settings: T,
    }
    let cmd = <Defaults<T> as clap::CommandFactory>::command();
    let cmd = cmd.mut_args(|a| a.env(None::<&str>));
    let matches = cmd
        .try_get_matches_from(["graybox"])
        .expect("the declared defaults parse");
    <Defaults<T> as clap::FromArgMatches>::from_arg_matches(&matches)
        .expect("the declared defaults parse")
        .settings
}

const MB: usize = 1 << 20;

/// An hour: longer is no grace but a hang (and a deadline far enough away overflows a clock).
pub const MAX_SHUTDOWN_GRACE_SECS: u64 = 3600;

/// A day: the longest lease (a job whose worker died waits for its lease to expire).
pub const MAX_LEASE_SECS: u64 = 24 * 3600;

/// A week: the most any of the waits the settings name may be (a longer one is a hang, and
/// a deadline far enough away overflows a clock).
pub const MAX_WAIT_SECS: u64 = 7 * 24 * 3600;

impl Settings {
    /// Checks the values together (each flag that counts something is at least 1; the
    /// threads the settings imply fit the runtime's cap).
    pub fn validate(&self) -> Result<()> {
        self.worker.validate()?;
        let at_least_one = [
            ("max-body-mb", self.max_body_mb),
            ("max-model-mb", self.max_model_mb),
            ("max-template-mb", self.max_template_mb),
            ("max-inflight-body-mb", self.max_inflight_body_mb),
            ("grpc-max-message-mb", self.grpc_max_message_mb),
            ("grpc-max-streams", self.grpc_max_streams as usize),
            ("max-call-memory-mb", self.max_call_memory_mb),
            ("max-heavy-calls", self.max_heavy_calls),
            ("max-short-calls", self.max_short_calls),
            ("max-job-memory-mb", self.max_job_memory_mb),
            ("max-model-params", self.max_model_params),
            ("max-dof", self.max_dof),
        ];
        at_least_one_each(&at_least_one)?;
        // Every body must fit the budget alone, or it could never be admitted.
        let budget = self.max_inflight_body_bytes();
        if let Some(kind) = super::uploads::BodyKind::ALL
            .into_iter()
            .find(|k| k.max_cost(self) > budget)
        {
            return Err(Error::invalid(
                "max-inflight-body-mb",
                format!(
                    "must be at least {} MiB: a {kind:?} body at its limit takes that much \
                     while it is parsed",
                    kind.max_cost(self).div_ceil(MB)
                ),
            ));
        }
        let dof = crate::physics::MAX_DOF;
        if self.max_dof > dof {
            return Err(Error::invalid(
                "max-dof",
                format!("must be at most {dof} (the most a template document may have)"),
            ));
        }
        // Long calls and rollout streams each get --max-heavy-calls threads, short calls
        // --max-short-calls; 8 spare for loads.
        let threads = self.worker.workers + 2 * self.max_heavy_calls + self.max_short_calls;
        if threads + 8 > MAX_BLOCKING_THREADS {
            return Err(Error::invalid(
                "workers",
                format!(
                    "--workers plus twice --max-heavy-calls plus --max-short-calls must be at \
                     most {}",
                    MAX_BLOCKING_THREADS - 8
                ),
            ));
        }
        Ok(())
    }

    pub fn max_body_bytes(&self) -> usize {
        self.max_body_mb.saturating_mul(MB)
    }

    pub fn max_model_bytes(&self) -> usize {
        self.max_model_mb.saturating_mul(MB)
    }

    pub fn max_template_bytes(&self) -> usize {
        self.max_template_mb.saturating_mul(MB)
    }

    pub fn max_inflight_body_bytes(&self) -> usize {
        self.max_inflight_body_mb.saturating_mul(MB)
    }

    pub fn grpc_max_message_bytes(&self) -> usize {
        self.grpc_max_message_mb.saturating_mul(MB)
    }

    pub fn max_call_memory_bytes(&self) -> usize {
        self.max_call_memory_mb.saturating_mul(MB)
    }

    pub fn max_job_memory_bytes(&self) -> usize {
        self.max_job_memory_mb.saturating_mul(MB)
    }

    /// The API token, if one is set (an empty one is none).
    pub fn token(&self) -> Option<&str> {
        self.api_token.as_deref().filter(|t| !t.is_empty())
    }
}

/// The first flag in `flags` whose value is 0 is an error.
fn at_least_one_each(flags: &[(&str, usize)]) -> Result<()> {
    match flags.iter().find(|(_, v)| *v == 0) {
        Some((flag, _)) => Err(Error::invalid(*flag, "must be at least 1")),
        None => Ok(()),
    }
}

impl WorkerSettings {
    /// Checks the worker's flags (the counts are at least 1, the grace and threads bounded).
    pub fn validate(&self) -> Result<()> {
        at_least_one_each(&[
            ("lease-secs", self.lease_secs as usize),
            ("max-attempts", self.max_attempts as usize),
            ("job-threads", self.job_threads.unwrap_or(1)),
            ("blobs-timeout-secs", self.blobs_timeout_secs as usize),
        ])?;
        if self.lease_secs > MAX_LEASE_SECS {
            return Err(Error::invalid(
                "lease-secs",
                format!("must be at most {MAX_LEASE_SECS} (a dead worker's job waits that long)"),
            ));
        }
        for (flag, secs) in [
            ("blobs-timeout-secs", self.blobs_timeout_secs),
            ("blobs-retry-secs", self.blobs_retry_secs),
            ("storage-patience-secs", self.storage_patience_secs),
        ] {
            if secs > MAX_WAIT_SECS {
                return Err(Error::invalid(
                    flag,
                    format!("must be at most {MAX_WAIT_SECS}"),
                ));
            }
        }
        if self.shutdown_grace_secs > MAX_SHUTDOWN_GRACE_SECS {
            return Err(Error::invalid(
                "shutdown-grace-secs",
                format!("must be at most {MAX_SHUTDOWN_GRACE_SECS}"),
            ));
        }
        let most = crate::train::shards::MAX_THREADS;
        if self.job_threads.is_some_and(|t| t > most) {
            return Err(Error::invalid(
                "job-threads",
                format!("must be at most {most}"),
            ));
        }
        Ok(())
    }

    /// Threads per training job: `--job-threads`, else the cores shared among the workers,
    /// so that jobs training at once do not oversubscribe the machine.
    pub fn job_threads(&self) -> usize {
        self.job_threads
            .unwrap_or_else(|| crate::train::shards::cores() / self.workers.max(1))
            .max(1)
    }

    /// Checkpoint interval in epochs (at least 1).
    pub fn checkpoint_epochs(&self) -> usize {
        self.checkpoint_every.max(1)
    }

    /// How the object store's calls are timed out and retried.
    pub fn blobs_retry(&self) -> crate::store::blobs::Retry {
        crate::store::blobs::Retry {
            timeout: std::time::Duration::from_secs(self.blobs_timeout_secs),
            retry_for: std::time::Duration::from_secs(self.blobs_retry_secs),
        }
    }

    /// How long a job's storage may keep failing before the job fails.
    pub fn storage_patience(&self) -> std::time::Duration {
        std::time::Duration::from_secs(self.storage_patience_secs)
    }

    /// How long a signalled shutdown waits for jobs and calls before it exits anyway.
    pub fn shutdown_grace(&self) -> std::time::Duration {
        std::time::Duration::from_secs(self.shutdown_grace_secs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_threads_share_the_cores_among_workers_unless_given() {
        let cores = crate::train::shards::cores();
        let s = |workers, job_threads| WorkerSettings {
            workers,
            job_threads,
            ..WorkerSettings::default()
        };
        assert_eq!(s(1, None).job_threads(), cores);
        assert_eq!(s(2, None).job_threads(), (cores / 2).max(1));
        assert_eq!(s(cores + 1, None).job_threads(), 1, "never 0");
        assert_eq!(s(4, Some(3)).job_threads(), 3);
        for bad in [0, crate::train::shards::MAX_THREADS + 1] {
            let err = s(1, Some(bad)).validate().unwrap_err().to_string();
            assert!(err.contains("job-threads"), "{err}");
        }
    }

    #[test]
    fn every_duration_is_bounded() {
        let bad = |set: &dyn Fn(&mut WorkerSettings), flag: &str| {
            let mut s = WorkerSettings::default();
            set(&mut s);
            let err = s.validate().unwrap_err().to_string();
            assert!(err.contains(flag), "{flag}: {err}");
        };
        for v in [MAX_LEASE_SECS + 1, 9_200_000_000_000_000, u64::MAX] {
            bad(&|s| s.lease_secs = v, "lease-secs");
        }
        for v in [MAX_WAIT_SECS + 1, u64::MAX] {
            bad(&|s| s.blobs_timeout_secs = v, "blobs-timeout-secs");
            bad(&|s| s.blobs_retry_secs = v, "blobs-retry-secs");
            bad(&|s| s.storage_patience_secs = v, "storage-patience-secs");
        }
        bad(&|s| s.blobs_timeout_secs = 0, "blobs-timeout-secs");
        let longest = WorkerSettings {
            lease_secs: MAX_LEASE_SECS,
            storage_patience_secs: MAX_WAIT_SECS,
            ..WorkerSettings::default()
        };
        longest.validate().unwrap();
    }

    #[test]
    fn shutdown_grace_is_bounded() {
        let s = |shutdown_grace_secs| Settings {
            worker: WorkerSettings {
                shutdown_grace_secs,
                ..WorkerSettings::default()
            },
            ..Settings::default()
        };
        assert!(WorkerSettings::default().shutdown_grace_secs < 30);
        for ok in [0, MAX_SHUTDOWN_GRACE_SECS] {
            s(ok).validate().unwrap();
        }
        for bad in [MAX_SHUTDOWN_GRACE_SECS + 1, u64::MAX] {
            let err = s(bad).validate().unwrap_err().to_string();
            assert!(err.contains("shutdown-grace-secs"), "{err}");
        }
    }
}

//! `graybox serve`: its flags and the runtime it starts the service on.

use std::path::PathBuf;

use clap::Args;

use crate::error::{Error, Result};

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// REST listen address.
    #[arg(long, env = "GRAYBOX_HTTP", default_value = "127.0.0.1:8080")]
    pub http: String,
    /// gRPC listen address.
    #[arg(long, env = "GRAYBOX_GRPC", default_value = "127.0.0.1:50051")]
    pub grpc: String,
    /// SQLite database file (created if missing).
    #[arg(long, env = "GRAYBOX_DB", default_value = "./graybox.db")]
    pub db: String,
    /// Training workers (jobs trained at once).
    #[arg(long, env = "GRAYBOX_WORKERS", default_value_t = 1)]
    pub workers: usize,
    /// Checkpoint a running job every this many epochs.
    #[arg(long, env = "GRAYBOX_CHECKPOINT_EVERY", default_value_t = 10)]
    pub checkpoint_every: usize,
    /// A job whose worker has not heartbeated for this long is reclaimed.
    #[arg(long, env = "GRAYBOX_LEASE_SECS", default_value_t = 30)]
    pub lease_secs: u64,
    /// Largest accepted request body, in MiB.
    #[arg(long, env = "GRAYBOX_MAX_BODY_MB", default_value_t = 256)]
    pub max_body_mb: usize,
    /// Longest gRPC Rollout, in steps.
    #[arg(long, env = "GRAYBOX_MAX_ROLLOUT_STEPS", default_value_t = 100_000)]
    pub max_rollout_steps: usize,
    /// Largest gRPC message, in MiB.
    #[arg(long, env = "GRAYBOX_GRPC_MAX_MESSAGE_MB", default_value_t = 64)]
    pub grpc_max_message_mb: usize,
    /// Concurrent gRPC calls (HTTP/2 streams) per connection.
    #[arg(long, env = "GRAYBOX_GRPC_MAX_STREAMS", default_value_t = 100)]
    pub grpc_max_streams: u32,
    /// Memory one inference call may take, in MiB (larger calls: RESOURCE_EXHAUSTED).
    #[arg(long, env = "GRAYBOX_MAX_CALL_MEMORY_MB", default_value_t = 512)]
    pub max_call_memory_mb: usize,
    /// Heavy inference calls computing at once (the others wait).
    #[arg(long, env = "GRAYBOX_MAX_HEAVY_CALLS", default_value_t = 2)]
    pub max_heavy_calls: usize,
    /// Estimated peak memory of one training job, in MiB (larger jobs: 422 at submission).
    #[arg(long, env = "GRAYBOX_MAX_JOB_MEMORY_MB", default_value_t = 4096)]
    pub max_job_memory_mb: usize,
    /// Trainable parameters of one model.
    #[arg(long, env = "GRAYBOX_MAX_MODEL_PARAMS", default_value_t = 1_000_000)]
    pub max_model_params: usize,
    /// Generalized coordinates n a job may train on.
    #[arg(long, env = "GRAYBOX_MAX_DOF", default_value_t = 64)]
    pub max_dof: usize,
    /// Times a job's worker may die (lease expired) before the job fails.
    #[arg(long, env = "GRAYBOX_MAX_ATTEMPTS", default_value_t = 3)]
    pub max_attempts: u32,
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

/// Blocking threads of the service's runtime: training jobs, heavy inference calls (at most
/// `--max-heavy-calls`) and model loads. A cap, so that no burst of requests can make the
/// process spawn hundreds of threads.
const MAX_BLOCKING_THREADS: usize = 32;

pub fn serve(a: ServeArgs) -> Result<()> {
    let cfg = config(a)?;
    let tls = cfg.tls.is_some();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .max_blocking_threads(MAX_BLOCKING_THREADS)
        .enable_all()
        .build()?;
    rt.block_on(async {
        let running = crate::service::start(cfg).await?;
        let scheme = if tls { "https" } else { "http" };
        eprintln!(
            "graybox: REST on {scheme}://{}, gRPC on {}{}",
            running.http_addr,
            running.grpc_addr,
            if tls { " (TLS)" } else { "" }
        );
        crate::service::signal().await;
        eprintln!("graybox: shutting down (running jobs are checkpointed at their next epoch end)");
        running.shutdown().await;
        Ok(())
    })
}

/// The flags checked and turned into the service's configuration.
fn config(a: ServeArgs) -> Result<crate::service::ServiceConfig> {
    let at_least_one = [
        ("lease-secs", a.lease_secs as usize),
        ("max-body-mb", a.max_body_mb),
        ("grpc-max-streams", a.grpc_max_streams as usize),
        ("max-call-memory-mb", a.max_call_memory_mb),
        ("max-heavy-calls", a.max_heavy_calls),
        ("max-job-memory-mb", a.max_job_memory_mb),
        ("max-model-params", a.max_model_params),
        ("max-dof", a.max_dof),
        ("max-attempts", a.max_attempts as usize),
    ];
    if let Some((flag, _)) = at_least_one.iter().find(|(_, v)| *v == 0) {
        return Err(Error::invalid(*flag, "must be at least 1"));
    }
    // Calls and rollout streams each get --max-heavy-calls threads; 8 spare for model loads.
    if a.workers + 2 * a.max_heavy_calls + 8 > MAX_BLOCKING_THREADS {
        return Err(Error::invalid(
            "workers",
            format!(
                "--workers plus twice --max-heavy-calls must be at most {}",
                MAX_BLOCKING_THREADS - 8
            ),
        ));
    }
    Ok(crate::service::ServiceConfig {
        http: a.http,
        grpc: a.grpc,
        db: a.db,
        settings: crate::app::Settings {
            workers: a.workers,
            checkpoint_every: a.checkpoint_every.max(1),
            lease_secs: a.lease_secs,
            max_body_bytes: a.max_body_mb << 20,
            max_rollout_steps: a.max_rollout_steps,
            grpc_max_message_bytes: a.grpc_max_message_mb << 20,
            grpc_max_streams: a.grpc_max_streams,
            max_call_memory_bytes: a.max_call_memory_mb << 20,
            max_heavy_calls: a.max_heavy_calls,
            max_job_memory_bytes: a.max_job_memory_mb << 20,
            max_model_params: a.max_model_params,
            max_dof: a.max_dof,
            max_attempts: a.max_attempts as i64,
        },
        rest: crate::api::rest::RestSettings {
            api_token: a.api_token.filter(|t| !t.is_empty()),
            auth_reads: a.auth_reads,
        },
        tls: a
            .tls_cert
            .zip(a.tls_key)
            .map(|(cert, key)| crate::api::listen::TlsFiles { cert, key }),
    })
}

//! `graybox serve`: its flags and the runtime it starts the service on.

use std::time::Duration;

use crate::app::Settings;
use crate::app::settings::MAX_BLOCKING_THREADS;
use crate::error::Result;
use crate::service::{Stopped, signal};

/// How long the runtime waits at exit for blocking threads. Their callers are gone by then,
/// which tells a solver to stop within a time step; a training thread abandoned mid-epoch
/// would take the rest of its epoch, and dropping the runtime would wait for it (a runaway
/// Plan once kept a SIGTERMed process alive).
const EXIT_WAIT: Duration = Duration::from_secs(1);

pub fn serve(settings: Settings) -> Result<()> {
    settings.validate()?;
    let tls = settings.tls_cert.is_some();
    let grace = settings.shutdown_grace();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .max_blocking_threads(MAX_BLOCKING_THREADS)
        .enable_all()
        .build()?;
    let served = rt.block_on(async {
        let running = crate::service::start(settings).await?;
        let scheme = if tls { "https" } else { "http" };
        eprintln!(
            "graybox: REST on {scheme}://{}, gRPC on {}{}",
            running.http_addr,
            running.grpc_addr,
            if tls { " (TLS)" } else { "" }
        );
        signal().await;
        eprintln!(
            "graybox: shutting down (running jobs are checkpointed at their next epoch end; \
             after {} s, or at a second signal, they go back from their last checkpoint)",
            grace.as_secs()
        );
        let force = async {
            tokio::select! {
                () = tokio::time::sleep(grace) => {}
                () = signal() => {}
            }
        };
        if let Stopped::Forced { released } = running.shutdown_by(force).await {
            eprintln!(
                "graybox: stopped without waiting: {released} job(s) given back to the queue \
                 from their last checkpoint"
            );
        }
        Ok(())
    });
    rt.shutdown_timeout(EXIT_WAIT);
    served
}

//! `graybox serve`, and the runtime and signal handling it shares with `graybox worker`.

use std::future::Future;
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
    let grace = settings.worker.shutdown_grace();
    long_running(async move {
        let running = crate::service::start(settings).await?;
        let scheme = if tls { "https" } else { "http" };
        eprintln!(
            "graybox: REST on {scheme}://{}, gRPC on {}{}; dashboard: {scheme}://{}/",
            running.http_addr,
            running.grpc_addr,
            if tls { " (TLS)" } else { "" },
            browsable(running.http_addr)
        );
        signal().await;
        announce_stop(grace);
        announce_forced(running.shutdown_by(until_forced(grace)).await);
        Ok(())
    })
}

/// The address a browser on this machine opens: a wildcard bind (`0.0.0.0`, `::`) is not one.
fn browsable(addr: std::net::SocketAddr) -> String {
    if addr.ip().is_unspecified() {
        format!("localhost:{}", addr.port())
    } else {
        addr.to_string()
    }
}

/// Runs a service process's future on a runtime with the capped blocking pool, and exits
/// without waiting long for computations nobody awaits any more.
pub(super) fn long_running(process: impl Future<Output = Result<()>>) -> Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .max_blocking_threads(MAX_BLOCKING_THREADS)
        .enable_all()
        .build()?;
    let done = rt.block_on(process);
    rt.shutdown_timeout(EXIT_WAIT);
    done
}

/// Resolves when the grace has run out or a second signal came.
pub(super) async fn until_forced(grace: Duration) {
    tokio::select! {
        () = tokio::time::sleep(grace) => {}
        () = signal() => {}
    }
}

pub(super) fn announce_stop(grace: Duration) {
    eprintln!(
        "graybox: shutting down (running jobs are checkpointed at their next epoch end; \
         after {} s, or at a second signal, they go back from their last checkpoint)",
        grace.as_secs()
    );
}

pub(super) fn announce_forced(stopped: Stopped) {
    if let Stopped::Forced { released } = stopped {
        eprintln!(
            "graybox: stopped without waiting: {released} job(s) given back to the queue \
             from their last checkpoint"
        );
    }
}
